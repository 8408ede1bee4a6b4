"""Errors of the bag tools. Each names the bag (or path) and what is wrong with it."""

from omni_micro_common.errors import OmniMicroError


class BagError(OmniMicroError):
    """Base class of the errors about bags."""


class BagPathError(BagError, ValueError):
    """A path that is not a bag, or where a bag cannot be written: the caller's mistake."""


class BagDamagedError(BagError, RuntimeError):
    """A bag that exists but cannot be read whole (truncated, corrupt, or empty)."""


class ReplayError(OmniMicroError, RuntimeError):
    """A replay that cannot go on: nobody subscribes, or a node it keeps pace with is silent."""
