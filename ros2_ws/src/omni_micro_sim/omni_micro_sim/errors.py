"""Errors raised by the slip core. Each names the offending value and what was expected."""


class OmniMicroSimError(Exception):
    """Base class of every error raised by omni_micro_sim."""


class ParameterError(OmniMicroSimError, ValueError):
    """A robot or motor parameter is outside its physical range."""


class CommandError(OmniMicroSimError, ValueError):
    """A wheel command (speed profile, steering angle, move duration) is malformed."""


class SimulationError(OmniMicroSimError, RuntimeError):
    """The integration produced a non-finite state: never returned silently."""
