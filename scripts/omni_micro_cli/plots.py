"""Plots in the style of the paper's figures, from plain arrays (SI in, mm and mm/s drawn)."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

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
           goal_m: Sequence[float] | None = None, captures_m: np.ndarray | None = None,
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
