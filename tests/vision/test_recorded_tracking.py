"""The noise a camera shows over its still frames, as `omni-micro track` reports it for the
camera's params (the frame loops themselves are tested through `track`, in tests/cli and
tests/graph)."""

import dataclasses
import math

import numpy as np
import pytest

from omni_micro_vision.recorded_tracking import still_spread
from omni_micro_vision.tracked_camera import tracked_camera


def macro():
    """The macro camera as tracker_node's defaults make it."""
    return tracked_camera('macro', lambda _name, default: default)


def rows_of(poses, still):
    """Frame rows as track_frames makes them: (stamp, found, still, x, y, heading, reason)."""
    return [(0.1 * index, True, flag, x, y, heading, '')
            for index, ((x, y, heading), flag) in enumerate(zip(poses, still, strict=True))]


def test_a_move_between_two_still_stretches_is_not_counted_as_noise():
    """Two stretches 10 mm apart, each scattered +-1 um in x about its own place: the spread
    is 1 um, not the 5 mm the move would add."""
    scatter = [-1e-6, 1e-6] * 3
    first = [(0.010 + dx, 0.0, 0.3) for dx in scatter]
    second = [(0.020 + dx, 0.0, 0.3) for dx in scatter]
    moving = [(0.015, 0.0, 0.3)]
    rows = rows_of(first + moving + second, [True] * 6 + [False] + [True] * 6)
    spread = still_spread(rows, macro())
    assert spread is not None
    assert math.isclose(spread.spread_m_rad[0], 1e-6, rel_tol=1e-6)
    assert spread.spread_m_rad[1] == 0.0 and spread.spread_m_rad[2] == 0.0


def test_the_noise_it_proposes_states_the_spread_it_measured():
    """Round trip: a camera given the noise_px and quantisation_px it proposes states, for the
    position, the spread its still frames showed."""
    camera = macro()
    rng = np.random.default_rng(7)
    sigma_m = 3e-6
    poses = [(0.05 + rng.normal(0, sigma_m), 0.01 + rng.normal(0, sigma_m), 0.3)
             for _ in range(400)]
    spread = still_spread(rows_of(poses, [True] * len(poses)), camera)
    assert spread is not None
    proposed = dataclasses.replace(camera, noise_px=spread.noise_px,
                                   quantisation_px=spread.quantisation_px)
    stated = proposed.uncertainty(0.3)
    measured = float(np.mean(spread.spread_m_rad[:2]))
    assert math.isclose(np.mean([stated.x_sigma_m, stated.y_sigma_m]), measured, rel_tol=0.02)


@pytest.mark.parametrize('still', [[True, False, True, False, True], [False, True, False],
                                   [False, False, False]])
def test_no_two_still_frames_in_a_row_measure_nothing(still):
    """Still frames each alone between moves scatter about nothing: no spread (not a NaN, not
    a failure)."""
    poses = [(0.01 * (index + 1), 0.0, 0.3) for index in range(len(still))]
    assert still_spread(rows_of(poses, still), macro()) is None
