"""Parsers for command-line values in the user's units (mm, deg), checked at the boundary."""

from __future__ import annotations

import argparse
import math
from typing import Callable


def finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'expected a finite number, got {text!r}')
    return value


def positive_float(text: str) -> float:
    value = finite_float(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f'expected a number > 0, got {text!r}')
    return value


def non_negative_float(text: str) -> float:
    value = finite_float(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f'expected a number >= 0, got {text!r}')
    return value


def probability(text: str) -> float:
    value = finite_float(text)
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f'expected a probability in [0, 1], got {text!r}')
    return value


def non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a whole number, got {text!r}') from None
    if value < 0:
        raise argparse.ArgumentTypeError(f'expected a whole number >= 0, got {text!r}')
    return value


def float_list(count: int, what: str) -> Callable[[str], tuple[float, ...]]:
    """A parser for ``count`` comma-separated finite numbers, e.g. ``0,3,2``."""

    def parse(text: str) -> tuple[float, ...]:
        parts = [part.strip() for part in text.split(',')]
        if len(parts) != count:
            raise argparse.ArgumentTypeError(
                f'expected {count} comma-separated {what}, got {text!r}')
        return tuple(finite_float(part) for part in parts)

    return parse
