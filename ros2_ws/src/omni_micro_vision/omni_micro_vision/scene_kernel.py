"""The scene's reflectance at a window of pixel centres, as one numba kernel.

:func:`omni_micro_vision.rendering.render` computes only the few blocks of a frame that an
outline (the chassis's edge, a dot) reaches; this is what fills one. With numpy, each block
took a dozen whole-window temporaries (a distance, a ramp, a clip per disc and per instant of
the exposure), most of them of pixels plainly in or out of a disc. Here each instant visits a
disc's pixels only along the rows and columns it can reach, and takes a distance
(``math.hypot``, as ``np.hypot`` did) only near an edge. Every value is the one the array
version computed, operation for operation: a frame is the same bit for bit
(tests/vision/test_scene_kernel.py keeps the array version as a reference).

Imported by ``render`` on first use, so that importing the camera model does not load numba.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]

# Spans found from the pixel pitch are widened by this many pixels: pixel centres are evenly
# spaced only to rounding, and each pixel in a span is still tested exactly.
_SPAN_MARGIN_PX = 2


@numba.njit(cache=True)
def _coverage(distance_m: float, radius_m: float, pixel_m: float) -> float:
    """How much of a pixel a disc covers from the distance of the pixel's centre to the disc's
    centre: a linear ramp one pixel wide across the edge, clipped to [0, 1]."""
    return min(max(0.5 - (distance_m - radius_m) / pixel_m, 0.0), 1.0)


@numba.njit(cache=True)
def _span(centres: Array, low_m: float, high_m: float) -> tuple[int, int]:
    """Indices [first, last) of the evenly spaced ``centres`` (either order) that may lie in
    [low_m, high_m]: a superset by ``_SPAN_MARGIN_PX`` each side, empty as first >= last."""
    count = centres.size
    if count == 1:
        return 0, 1
    pitch = (centres[count - 1] - centres[0]) / (count - 1)
    first_m, last_m = (low_m, high_m) if pitch > 0 else (high_m, low_m)
    first = math.floor((first_m - centres[0]) / pitch) - _SPAN_MARGIN_PX
    last = math.ceil((last_m - centres[0]) / pitch) + 1 + _SPAN_MARGIN_PX
    return max(first, 0), min(last, count)


@numba.njit(cache=True)
def _inner2(radius_m: float, pixel_m: float) -> float:
    """The squared distance within which a disc covers a whole pixel, or -1 (none: a disc
    smaller than a pixel covers at most part of one)."""
    return (radius_m - pixel_m) ** 2 if radius_m > pixel_m else -1.0


@numba.njit(cache=True)
def reflectance_sum(xs: Array, ys: Array, centres_x: Array, centres_y: Array,
                    chassis_fills: npt.NDArray[np.bool_], dots_x: Array, dots_y: Array,
                    dot_radii: Array, pixel_m: float, chassis_radius_m: float,
                    platform_level: float, chassis_level: float, dot_level: float) -> Array:
    """The reflectance at ``xs`` x ``ys`` summed over the instants of an exposure.

    Instant k has the robot's centre at (``centres_x[k]``, ``centres_y[k]``) and dot j at
    (``dots_x[k, j]``, ``dots_y[k, j]``) of radius ``dot_radii[j]``, drawn in order over the
    chassis, which fills the window where ``chassis_fills[k]``. A disc covers exactly 0 of a
    pixel whose centre is a pixel or more past its edge, and exactly 1 of one a pixel or more
    inside: there the value is set without a distance (the margins dwarf the squares'
    rounding, and either way the clip gives the same 0 or 1).
    """
    image = np.zeros((ys.size, xs.size))
    instant = np.empty((ys.size, xs.size))
    contrast = chassis_level - platform_level
    inside_level = platform_level + contrast * 1.0
    outer2 = (chassis_radius_m + pixel_m) ** 2
    inner2 = _inner2(chassis_radius_m, pixel_m)
    for k in range(centres_x.size):
        cx, cy = centres_x[k], centres_y[k]
        if chassis_fills[k]:
            instant[:, :] = chassis_level
        else:
            instant[:, :] = platform_level + contrast * 0.0
            first_row, last_row = _span(ys, cy - chassis_radius_m - pixel_m,
                                        cy + chassis_radius_m + pixel_m)
            for row in range(first_row, last_row):
                dy = ys[row] - cy
                half_chord2 = outer2 - dy * dy
                if half_chord2 < 0.0:
                    continue
                half_chord = math.sqrt(half_chord2)
                first, last = _span(xs, cx - half_chord, cx + half_chord)
                for column in range(first, last):
                    dx = xs[column] - cx
                    distance2 = dx * dx + dy * dy
                    if distance2 >= outer2:
                        continue
                    if distance2 <= inner2:
                        instant[row, column] = inside_level
                    else:
                        instant[row, column] = platform_level + contrast * _coverage(
                            math.hypot(dx, dy), chassis_radius_m, pixel_m)
        for dot in range(dot_radii.size):
            radius = dot_radii[dot]
            reach = radius + pixel_m
            dot_x, dot_y = dots_x[k, dot], dots_y[k, dot]
            dot_outer2 = reach * reach
            dot_inner2 = _inner2(radius, pixel_m)
            first_row, last_row = _span(ys, dot_y - reach, dot_y + reach)
            first, last = _span(xs, dot_x - reach, dot_x + reach)
            for row in range(first_row, last_row):
                dy = ys[row] - dot_y
                if abs(dy) > reach:
                    continue
                for column in range(first, last):
                    dx = xs[column] - dot_x
                    if abs(dx) > reach:
                        continue
                    distance2 = dx * dx + dy * dy
                    if distance2 >= dot_outer2:
                        continue    # covers 0: the value stays as it is
                    value = instant[row, column]
                    if distance2 <= dot_inner2:
                        instant[row, column] = value + (dot_level - value) * 1.0
                    else:
                        instant[row, column] = value + (dot_level - value) * _coverage(
                            math.hypot(dx, dy), radius, pixel_m)
        image += instant
    return image
