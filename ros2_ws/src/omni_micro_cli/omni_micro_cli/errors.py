"""Errors of the command line. A UsageError exits with status 2 and names the bad value."""

from omni_micro_common.errors import OmniMicroError


class UsageError(OmniMicroError, ValueError):
    """A command-line value is malformed or out of range."""


class RunFailed(OmniMicroError, RuntimeError):  # noqa: N818 - an outcome, named as the CLI reports it
    """A run did not reach its goal, or a node failed; the message names what failed."""


class StudyError(UsageError):
    """A study file is malformed or asks for something out of range; the message names the key
    and the value."""
