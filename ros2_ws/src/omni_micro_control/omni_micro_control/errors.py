"""Errors of the controller and of identification; each names the value or says why."""

from omni_micro_common.errors import OmniMicroError


class ControllerConfigError(OmniMicroError, ValueError):
    """A controller parameter is out of range; the message names it."""


class IdentificationError(OmniMicroError, ValueError):
    """The data cannot give the parameters asked for; the message says why."""


class RecordingError(OmniMicroError, ValueError):
    """A recorded message cannot be read as what its topic promises; the message says which."""


class FleetFileError(OmniMicroError, ValueError):
    """A fleet's robots or tasks (a file, or a count) cannot be used; the message names the
    value and where it is."""
