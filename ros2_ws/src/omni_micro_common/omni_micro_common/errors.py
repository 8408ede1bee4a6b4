"""Errors every omni-micro package raises. Each names the offending value and what was expected."""


class OmniMicroError(Exception):
    """Base class of the errors the omni-micro packages raise on purpose."""


class ParameterError(OmniMicroError, ValueError):
    """A parameter (of a node, the robot or the motors) is outside what it may be."""


class CommandError(OmniMicroError, ValueError):
    """A command (a wheel trajectory, a steering angle, a move duration) is malformed."""


class ParamsFileError(ParameterError):
    """A params file cannot be read, is not YAML, or is not shaped as ROS 2 expects."""


class LockstepError(OmniMicroError, ValueError):
    """A lockstep report or setting is malformed; the message names the value."""
