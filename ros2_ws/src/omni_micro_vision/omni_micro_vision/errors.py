"""Errors of the camera model, the renderer and the tracker; each names the value."""

from omni_micro_common.errors import OmniMicroError


class CameraConfigError(OmniMicroError, ValueError):
    """A camera or capture parameter is out of range; the message names it."""


class AnimationError(OmniMicroError, ValueError):
    """A run that cannot be animated as asked (nothing to draw, a format this machine cannot
    write); the message says what."""
