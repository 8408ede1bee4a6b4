"""Errors raised by the slip core. Each names the offending value and what was expected.

A bad parameter or command is the same error in every package (:mod:`omni_micro_common.errors`),
so that one ``except ParameterError`` catches it wherever it was raised.
"""

from omni_micro_common.errors import CommandError, OmniMicroError, ParameterError

__all__ = ['CommandError', 'OmniMicroSimError', 'ParameterError', 'SimulationError']


class OmniMicroSimError(OmniMicroError):
    """Base class of the errors only the slip core raises."""


class SimulationError(OmniMicroSimError, RuntimeError):
    """The integration produced a non-finite state: never returned silently."""
