"""Errors of the studies. A StudyError names the key and the value of a study that cannot be run
(a ValueError: exit 2 on the command line)."""

from omni_micro_common.errors import OmniMicroError


class StudyError(OmniMicroError, ValueError):
    """A study file is malformed or asks for something out of range; the message names the key
    and the value."""
