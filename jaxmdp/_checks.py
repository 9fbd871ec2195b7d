"""Host-side argument checks and literals shared by jaxmdp, the agents and the hardness measures.

Every check raises ``ValueError`` naming the parameter and what is allowed, and runs on the host before anything
compiles (values are Python or numpy numbers, or whole hyperparameter grids).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable
from typing import Any, Literal

import numpy as np

__all__ = ["Variant", "VARIANTS", "check_variant", "check_bool", "check_int", "check_range", "did_you_mean"]

#: Which definition a measure or an indicator follows: ``"paper"`` (the paper's, computed exactly) or
#: ``"colosseum"`` (the reference package's procedure and numbers, docs/measures.md).
Variant = Literal["paper", "colosseum"]
VARIANTS: tuple[str, ...] = ("paper", "colosseum")


def did_you_mean(value: Any, known: Iterable[str], cutoff: float = 0.4) -> str:
    """``"; did you mean 'a', 'b'?"`` naming the (at most three) names of ``known`` closest to ``value`` (difflib
    ratio at least ``cutoff``), or ``""`` when none is close: the hint of an unknown-name error."""
    close = difflib.get_close_matches(str(value), list(known), n=3, cutoff=cutoff)
    return f"; did you mean {', '.join(map(repr, close))}?" if close else ""


def check_variant(variant: Any, name: str = "variant") -> None:
    """Raise ``ValueError`` (naming the parameter ``name``) unless ``variant`` is one of :data:`VARIANTS`."""
    if variant not in VARIANTS:
        raise ValueError(f"{name} must be 'paper' or 'colosseum'; got {variant!r}")


def check_bool(name: str, value: Any) -> bool:
    """``value`` after checking that it is ``True`` or ``False`` (a switch given as 1 or "yes" is refused)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False; got {value!r}")
    return bool(value)


def check_int(name: str, value: Any, low: int = 1, high: float | None = None, *, context: str = "") -> int:
    """``value`` as an ``int`` after checking that it is an integer (bools refused) in ``[low, high]``.

    ``context`` is appended to the allowed range in the message (e.g. ``" for Taxi"``).
    """
    bound = f">= {low}" if high is None or math.isinf(high) else f"in [{low}, {high}]"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer {bound}{context}; got {value!r}")
    if value < low or (high is not None and value > high):
        raise ValueError(f"{name} must be an integer {bound}{context}; got {value}")
    return int(value)


def check_range(
    name: str,
    value: Any,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> None:
    """Raise ``ValueError`` unless every entry of ``value`` is finite and in the interval from ``low`` to ``high``
    (closed unless ``low_open``/``high_open``).

    ``value`` may be a scalar or an array (a hyperparameter grid) of numbers (a string is refused, not parsed); the
    first offending entry is reported.
    """
    raw = np.asarray(value)
    if raw.dtype.kind not in "biuf":
        raise ValueError(f"{name} must be a number; got {value!r}")
    x = raw.astype(np.float64)
    ok = np.isfinite(x)
    ok &= (x > low) if low_open else (x >= low)
    ok &= (x < high) if high_open else (x <= high)
    if not np.all(ok):
        bad = x.reshape(-1)[np.argmin(ok.reshape(-1))]
        interval = f"{'(' if low_open else '['}{low}, {high}{')' if high_open else ']'}"
        raise ValueError(f"{name} must be finite and in {interval}; got {bad}")
