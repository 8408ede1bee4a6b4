"""Errors of the command line. A UsageError exits with status 2 and names the bad value; a
RunFailed exits with 1 (both are the bringup's, which the commands run)."""

from omni_micro_bringup.errors import RunFailed, UsageError

__all__ = ['RunFailed', 'StudyError', 'UsageError']


class StudyError(UsageError):
    """A study file is malformed or asks for something out of range; the message names the key
    and the value."""
