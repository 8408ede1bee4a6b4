"""The ``/controller/status`` message a controller publishes: what it says, at the simulated time
of what it says (``STATUS_TIME_KEY``). Beside the contracts, for whoever else writes a
controller's status into a bag (the fleet twin's bag)."""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from omni_micro_common.conventions import STATUS_TIME_KEY


def status_message(level: int, message: str, at_s: float, values: dict[str, str]
                   ) -> DiagnosticStatus:
    """``at_s``: the simulated time of what the status says (a decision's capture, a goal's
    arrival), not of its publication: a bag records it at that time (STATUS_TIME_KEY), so
    that the same run records the same statuses in the same place."""
    status = DiagnosticStatus(level=level, name='omni_micro_controller', message=message,
                              hardware_id='omni_micro')
    values = {STATUS_TIME_KEY: repr(float(at_s)), **values}
    status.values = [KeyValue(key=key, value=value) for key, value in values.items()]
    return status
