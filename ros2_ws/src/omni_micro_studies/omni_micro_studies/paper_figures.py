"""Plots in the style of the paper's figures, from plain arrays (SI in, mm and mm/s drawn)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt
import numpy as np

WHEEL_COLOURS = ('tab:blue', 'tab:orange', 'tab:green')


def _save(figure: plt.Figure, path: Path) -> None:
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def drift_curves(path: Path, x: np.ndarray, curves: dict[str, np.ndarray], *, xlabel: str,
                 title: str) -> None:
    """Drift (m) against a swept quantity, one line per label."""
    figure, axes = plt.subplots(figsize=(6.4, 4.2))
    for label, drift_m in curves.items():
        axes.plot(x, np.asarray(drift_m) * 1e3, label=label)
    axes.set_xlabel(xlabel)
    axes.set_ylabel('drift from the goal (mm)')
    axes.set_title(title)
    axes.grid(True, alpha=0.3)
    axes.legend()
    _save(figure, path)


def wheel_slip(path: Path, time_s: np.ndarray, slip_m_s: np.ndarray, *, component: str,
               title: str) -> None:
    """Slip of each wheel (columns of ``slip_m_s``, m/s) against time."""
    figure, axes = plt.subplots(figsize=(6.4, 4.2))
    for k in range(slip_m_s.shape[1]):
        axes.plot(time_s, slip_m_s[:, k] * 1e3, color=WHEEL_COLOURS[k], label=f'wheel {k + 1}')
    axes.set_xlabel('time (s)')
    axes.set_ylabel(f'{component} slip velocity (mm/s)')
    axes.set_title(title)
    axes.grid(True, alpha=0.3)
    axes.legend()
    _save(figure, path)


def routes(path: Path, routes_m: dict[str, np.ndarray], *, ideal_m: np.ndarray | None = None,
           goal_m: Sequence[float] | np.ndarray | None = None,
           captures_m: np.ndarray | None = None,
           title: str, equal_aspect: bool = False) -> None:
    """Routes (N x 2 arrays of x, y in m) against the ideal straight route."""
    figure, axes = plt.subplots(figsize=(7.0, 4.2))
    if ideal_m is not None:
        axes.plot(ideal_m[:, 0] * 1e3, ideal_m[:, 1] * 1e3, 'k--', lw=1, label='ideal route')
    for label, route in routes_m.items():
        axes.plot(route[:, 0] * 1e3, route[:, 1] * 1e3, label=label)
    if captures_m is not None and len(captures_m):
        axes.plot(captures_m[:, 0] * 1e3, captures_m[:, 1] * 1e3, '.', ms=4, color='tab:red',
                  label='camera captures')
    if goal_m is not None:
        axes.plot(goal_m[0] * 1e3, goal_m[1] * 1e3, 'k*', ms=10, label='goal')
    axes.set_xlabel('x (mm)')
    axes.set_ylabel('y (mm)')
    axes.set_title(title)
    axes.grid(True, alpha=0.3)
    if equal_aspect:
        axes.set_aspect('equal', adjustable='datalim')
    axes.legend()
    _save(figure, path)


def closed_loop_comparison(path: Path, open_loop_m: np.ndarray, closed_loop_m: np.ndarray,
                           captures_m: np.ndarray, goal_m: Sequence[float], *,
                           zoom_half_width_m: float, title: str) -> None:
    """Fig. 11 beside its close-up: open- and closed-loop routes, capture points, the goal.

    The close-up (``zoom_half_width_m`` around the goal, in um) shows the last moves, which are
    invisible at the platform's scale.
    """
    figure, (whole, close) = plt.subplots(1, 2, figsize=(11.0, 4.4))
    for axes, scale, unit in ((whole, 1e3, 'mm'), (close, 1e6, 'um')):
        origin = np.zeros(2) if axes is whole else np.asarray(goal_m)
        for label, route, style in (('open loop', open_loop_m, '-'),
                                    ('vision feedback', closed_loop_m, '-')):
            if len(route):
                axes.plot((route[:, 0] - origin[0]) * scale, (route[:, 1] - origin[1]) * scale,
                          style, lw=1.2, label=label)
        if len(captures_m):
            axes.plot((captures_m[:, 0] - origin[0]) * scale,
                      (captures_m[:, 1] - origin[1]) * scale, '.', ms=4, color='tab:red',
                      label='captures used')
        axes.plot((goal_m[0] - origin[0]) * scale, (goal_m[1] - origin[1]) * scale, 'k*',
                  ms=11, label='goal')
        axes.grid(True, alpha=0.3)
        axes.set_xlabel(f'x ({unit}){" from the goal" if axes is close else ""}')
        axes.set_ylabel(f'y ({unit}){" from the goal" if axes is close else ""}')
    limit = zoom_half_width_m * 1e6
    close.set_xlim(-limit, limit)
    close.set_ylim(-limit, limit)
    close.set_aspect('equal')
    close.set_title('close-up of the goal')
    whole.set_title(title)
    whole.legend(loc='best')
    _save(figure, path)


def remaining_distance(path: Path, periods_remaining: np.ndarray) -> None:
    """Distance to the goal seen at each period's start (log scale): the comparator at work."""
    figure, axes = plt.subplots(figsize=(6.4, 4.2))
    axes.semilogy(periods_remaining[:, 0], periods_remaining[:, 1] * 1e3, 'o-', ms=3)
    axes.axhline(2.0, color='k', ls=':', lw=1, label='comparator, 2 mm')
    axes.set_xlabel('period')
    axes.set_ylabel('distance to the goal seen by the camera (mm)')
    axes.set_title('distance left at each period')
    axes.grid(True, which='both', alpha=0.3)
    axes.legend()
    _save(figure, path)


def steering_turn(path: Path, steering_deg: np.ndarray, turns_rad: dict[float, np.ndarray],
                  creep_ratio: dict[float, float]) -> None:
    """Chassis heading turned by a steering-only move against the steering angle, one line per
    contact radius (m), with the linear creep law's prediction dashed."""
    figure, axes = plt.subplots(figsize=(6.8, 4.4))
    for index, (radius, turns) in enumerate(turns_rad.items()):
        colour = plt.get_cmap('viridis')(index / max(1, len(turns_rad) - 1))
        axes.plot(steering_deg, np.degrees(turns) * 1e3, color=colour, marker='o',
                  markersize=3, label=f'a = {radius * 1e6:g} um')
        axes.plot(steering_deg, -steering_deg * creep_ratio[radius] * 1e3, color=colour,
                  linestyle='--', linewidth=0.8)
    axes.plot([], [], color='grey', linestyle='--', linewidth=0.8,
              label='linear creep law: -kappa a^2 / (L^2 + kappa a^2)')
    axes.set_xlabel('steering turned at rest (deg)')
    axes.set_ylabel('chassis heading turned (mdeg)')
    axes.set_title('Steering at rest turns the chassis against it (realistic steering)')
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=8)
    _save(figure, path)
