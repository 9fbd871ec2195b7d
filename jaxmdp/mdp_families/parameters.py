"""Host-side validation of integer family parameters (sizes, counts)."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["integer_parameter"]


def integer_parameter(name: str, value: Any, minimum: int, family: str, maximum: int | None = None) -> int:
    """``value`` as an ``int`` after checking ``minimum <= value (<= maximum)``.

    Raises:
      ValueError: naming ``name``, ``family`` and the allowed range when ``value`` is not an integer (bools are
        rejected) or lies outside the range.
    """
    bound = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer {bound} for {family}; got {value!r}")
    if value < minimum or (maximum is not None and value > maximum):
        raise ValueError(f"{name} must be an integer {bound} for {family}; got {value}")
    return int(value)
