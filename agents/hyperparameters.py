"""Host-side validation of agent hyperparameters (scalars or whole grids)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["check_range", "check_int"]


def check_range(
    name: str,
    value: Any,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> None:
    """Raise ``ValueError`` unless every entry of ``value`` is finite and in the interval ``low .. high``.

    ``value`` may be a scalar or an array (a hyperparameter grid); the first offending entry is reported.
    """
    x = np.asarray(value, dtype=np.float64)
    ok = np.isfinite(x)
    ok &= (x > low) if low_open else (x >= low)
    ok &= (x < high) if high_open else (x <= high)
    if not np.all(ok):
        bad = x.reshape(-1)[np.argmin(ok.reshape(-1))]
        interval = f"{'(' if low_open else '['}{low}, {high}{')' if high_open else ']'}"
        raise ValueError(f"{name} must be finite and in {interval}; got {bad}")


def check_int(name: str, value: Any, low: int, high: float = math.inf) -> None:
    """Raise ``ValueError`` unless ``value`` is a Python integer in ``[low, high]`` (a static size)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
        raise ValueError(f"{name} must be an integer in [{low}, {high}]; got {value!r}")
