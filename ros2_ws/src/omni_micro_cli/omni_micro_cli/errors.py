"""Errors of the command line. A UsageError exits with status 2 and names the bad value; a
RunFailed exits with 1 (both are the bringup's, which the commands run); a StudyError (a study
that cannot be run) is the studies' and exits with 2."""

from omni_micro_bringup.errors import RunFailed, UsageError
from omni_micro_studies.errors import StudyError

__all__ = ['RunFailed', 'StudyError', 'UsageError']
