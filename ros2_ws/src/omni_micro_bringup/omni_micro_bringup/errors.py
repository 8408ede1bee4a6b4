"""Errors of bringing the graph up. A UsageError names a value that cannot be used (exit 2 on
the command line); RunFailed says why a run did not end as asked (exit 1)."""

from omni_micro_common.errors import OmniMicroError


class UsageError(OmniMicroError, ValueError):
    """A value (an option, a params file, a goal) is malformed or out of range."""


class RunFailed(OmniMicroError, RuntimeError):  # noqa: N818 - an outcome, named as the CLI reports it
    """A run did not reach its goal, or a node failed; the message names what failed."""
