"""Which clock a stamp was taken on, and when two stamps cannot share one.

Every node here takes its time from message stamps. The simulated robot stamps from 0 (or
from the wall clock with ``stamp_origin: wall``); a real driver stamps the wall clock (ROS time,
seconds since 1970). A capture or a trajectory stamped on another clock than the robot's would
be waited for until the end of time: it is named instead, with both clocks and what to set.
No rclpy.
"""

from __future__ import annotations

import datetime

# Stamps further apart than this are on different clocks (a move is planned 50 ms ahead; a
# camera's latency is milliseconds; two machines' clocks in sync differ by far less).
CLOCK_MISMATCH_S = 60.0
# Stamps after this (2001-09-09) are read as the wall clock; a simulated run never gets there.
WALL_CLOCK_FROM_S = 1.0e9


def is_wall_clock(stamp_s: float) -> bool:
    return stamp_s >= WALL_CLOCK_FROM_S


def describe_clock(stamp_s: float) -> str:
    """A stamp with the clock it reads as, for a message a person reads."""
    if is_wall_clock(stamp_s):
        when = datetime.datetime.fromtimestamp(stamp_s, datetime.UTC)
        return f'{stamp_s:.3f} s (the wall clock, {when:%Y-%m-%d %H:%M:%S} UTC)'
    return f'{stamp_s:.3f} s (a clock from 0: simulated time)'


def clock_mismatch(what: str, stamp_s: float, whose: str, now_s: float) -> str | None:
    """Why ``what``, stamped ``stamp_s``, cannot be on the clock of ``whose``, which reads
    ``now_s`` (None: it can)."""
    if abs(stamp_s - now_s) <= CLOCK_MISMATCH_S:
        return None
    if is_wall_clock(stamp_s) and not is_wall_clock(now_s):
        advice = ('a real driver stamps the wall clock: run with --camera external or --robot '
                  'external, which put the simulated part on the wall clock too (dynamics_node '
                  'stamp_origin: wall)')
    elif is_wall_clock(now_s) and not is_wall_clock(stamp_s):
        advice = ('a simulated or replayed source stamps from 0 while the robot runs on the wall '
                  'clock: run the simulated part with stamp_origin: wall, or replay with '
                  '--clock onto a simulated robot')
    else:
        advice = (f'the clocks differ by {abs(stamp_s - now_s) / 3600:.2f} h: synchronise the '
                  "machines' clocks (chrony, PTP)")
    return (f'{what} is stamped {describe_clock(stamp_s)} but {whose} runs on '
            f'{describe_clock(now_s)}: {advice}')
