"""All three measures at once, and the min-max normalisation of paper App. E."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from hardness.diameter import diameter
from hardness.gaps import sum_reciprocal_gaps_from
from hardness.result import MeasureResult
from hardness.value_norm import _host_continuous_form, optimal_values, value_norm_from
from jaxmdp import struct
from jaxmdp._checks import Variant, check_range, check_variant
from jaxmdp.episodic import ContinuousForm
from jaxmdp.mdp import MDP

__all__ = ["HardnessMeasures", "measures", "normalize"]

#: A compared set whose range is below this is mapped to 0.5 (docs/measures.md §6.5).
NORMALIZE_MIN_RANGE = 1e-4


class HardnessMeasures(struct.PyTreeNode):
    """The three measures of paper §2.2 as :class:`MeasureResult` s."""

    diameter: MeasureResult
    value_norm: MeasureResult
    sum_reciprocal_gaps: MeasureResult


def measures(
    mdp: MDP,
    gamma: float = 0.99,
    *,
    variant: Variant = "paper",
    continuous_form: ContinuousForm | None = None,
) -> HardnessMeasures:
    """Diameter, (discounted) environmental value norm and regularised sum of reciprocal gaps of ``mdp``, each with
    its defaults; ``continuous_form`` as in :func:`hardness.value_norm` (colosseum variant of episodic MDPs). The
    optimal values of a continuous MDP are computed once and shared by the value norm and the gap sum."""
    check_variant(variant)
    check_range("gamma", gamma, 0.0, 1.0, low_open=True, high_open=True)
    cf = None
    if variant == "colosseum" and mdp.episodic:
        cf = continuous_form if continuous_form is not None else _host_continuous_form(mdp)
    return HardnessMeasures(
        diameter=diameter(mdp, variant=variant),
        **_shared(mdp.strip(), cf, jnp.asarray(gamma, mdp.dtype), variant),
    )


@functools.partial(jax.jit, static_argnames=("variant",))
def _shared(mdp, cf, gamma, variant):
    values = None if mdp.episodic else optimal_values(mdp, gamma, variant)
    dt = mdp.dtype
    return dict(
        value_norm=value_norm_from(mdp, cf, gamma, variant, True, 1_000_000, values),
        sum_reciprocal_gaps=sum_reciprocal_gaps_from(
            mdp, gamma, jnp.asarray(0.1, dt), jnp.asarray(1e-5, dt), variant, "regularized", 1_000_000, values
        ),
    )


@functools.partial(jax.jit, static_argnames=("axis",))
def normalize(values: jax.Array, axis: int | tuple[int, ...] | None = None) -> jax.Array:
    """Min-max scaling to ``[0, 1]`` across the compared set (paper App. E): ``(x - min) / (max - min)`` along
    ``axis`` (all axes by default). A set whose range is below ``1e-4`` maps to 0.5 (docs/measures.md §6.5). Non-finite
    entries (an infinite diameter) are left out of the minimum and maximum and map to NaN."""
    x = jnp.asarray(values)
    finite = jnp.isfinite(x)
    lo = jnp.min(jnp.where(finite, x, jnp.inf), axis=axis, keepdims=True)
    hi = jnp.max(jnp.where(finite, x, -jnp.inf), axis=axis, keepdims=True)
    rng = hi - lo
    flat = ~(rng >= NORMALIZE_MIN_RANGE)  # also catches a set with no finite entry
    out = jnp.where(flat, 0.5, (x - lo) / jnp.where(flat, 1.0, rng))
    return jnp.where(finite, out, jnp.nan)
