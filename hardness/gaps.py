"""Sum of the reciprocals of the sub-optimality gaps (paper §2.2, Simchowitz & Jamieson 2019; docs/measures.md §5).

Gaps: ``Delta(s, a) = V*(s) - Q*(s, a)`` (continuous, discounted with ``gamma``) and
``Delta_h(s, a) = V*_h(s) - Q*_h(s, a)`` (episodic, exact finite-horizon values).

Two forms:

* ``form="regularized"`` (default): ``G = sum_{(s,a)} 1 / (Delta(s, a) + 0.1)`` over *all* valid pairs, optimal ones
  included (each adds ``1 / 0.1 = 10``); episodic: over the reachable pairs ``(h, s)`` (the states of the
  time-augmented MDP) and every valid action. This is the reference's form [paper≠code]; it is the default, an
  exception to the paper-first rule, because the paper itself warns that the raw form is numerically fragile (a
  near-zero gap dominates the sum).
* ``form="raw"``: the paper's ``sum_{Delta(s,a) != 0} 1 / Delta(s, a)``. In floating point a gap counts as zero when
  ``Delta <= zero_tol * max(1, max |V*|)`` (default ``zero_tol = 1e-5``, a few float32 ulps of the values); below
  that it is round-off of tied actions, not a gap.

Variants pick the values: ``"paper"`` uses the exact optimal values
(:func:`~jaxmdp.dynamic_programming.solve_discounted`); ``"colosseum"`` uses the reference's value iteration
(``eps = 1e-3``, :mod:`hardness.reference_vi`), whose last-sweep ``Q``/``V`` give the reference's numbers. Episodic
values are exact backward induction in both variants.
"""

from __future__ import annotations

import functools
from typing import Literal

import chex
import jax
import jax.numpy as jnp

from hardness.result import MeasureResult
from hardness.value_norm import optimal_values
from jaxmdp import dynamic_programming as dp
from jaxmdp._asserts import assert_mdp
from jaxmdp._checks import Variant, check_range, check_variant
from jaxmdp.episodic import reachable_pairs
from jaxmdp.mdp import MDP

__all__ = ["sum_reciprocal_gaps", "sum_reciprocal_gaps_from", "suboptimality_gaps"]

Form = Literal["regularized", "raw"]


def suboptimality_gaps(
    mdp: MDP,
    gamma: float | jax.Array = 0.99,
    *,
    variant: Variant = "paper",
    max_iter: int = 1_000_000,
    values: tuple[jax.Array, jax.Array, jax.Array] | None = None,
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """``(Delta, mask, V_scale, converged)``: the gaps (``[S, A]`` or ``[H, S, A]``), the pairs the sum runs over,
    the largest ``|V*|`` (for the raw form's zero threshold) and whether the values converged. Traceable;
    ``values`` = :func:`hardness.value_norm.optimal_values` of a continuous MDP if already computed."""
    S, A = assert_mdp(mdp)
    if values is not None:
        chex.assert_shape(values[:2], [(S, A), (S,)], custom_message="values: (Q [S, A], V [S], converged)")
    if mdp.episodic:
        Q, V = dp.finite_horizon_value_iteration(mdp)
        delta = V[:-1, :, None] - Q
        mask = reachable_pairs(mdp)[:, :, None] & mdp.action_mask[None, None, :]
        return delta, mask, jnp.max(jnp.abs(V)), jnp.asarray(True)
    Q, V, converged = optimal_values(mdp, gamma, variant, max_iter) if values is None else values
    if variant == "paper":
        V = jnp.max(jnp.where(mdp.action_mask, Q, -jnp.inf), axis=-1)  # Delta >= 0 exactly, one zero per state
    mask = mdp.state_mask[:, None] & mdp.action_mask[None, :]
    return V[:, None] - Q, mask, jnp.max(jnp.abs(V)), converged


def sum_reciprocal_gaps_from(mdp, gamma, regularizer, zero_tol, variant, form, max_iter, values=None):
    """Traceable core of :func:`sum_reciprocal_gaps` (``values`` as in :func:`suboptimality_gaps`)."""
    chex.assert_rank([regularizer, zero_tol], 0, custom_message="regularizer and zero_tol: scalars")
    delta, mask, scale, converged = suboptimality_gaps(mdp, gamma, variant=variant, max_iter=max_iter, values=values)
    if form == "regularized":
        terms = jnp.where(mask, 1.0 / (delta + regularizer), 0.0)
    else:
        nonzero = mask & (delta > zero_tol * jnp.maximum(1.0, scale))
        terms = jnp.where(nonzero, 1.0 / jnp.where(nonzero, delta, 1.0), 0.0)
    return MeasureResult.make(jnp.sum(terms), converged)


_sum_reciprocal_gaps = functools.partial(jax.jit, static_argnames=("variant", "form", "max_iter"))(
    sum_reciprocal_gaps_from
)


def sum_reciprocal_gaps(
    mdp: MDP,
    gamma: float = 0.99,
    *,
    variant: Variant = "paper",
    form: Form = "regularized",
    regularizer: float = 0.1,
    zero_tol: float = 1e-5,
    max_iter: int = 1_000_000,
) -> MeasureResult:
    """Sum of the reciprocal sub-optimality gaps of ``mdp`` (module docstring).

    Args:
      mdp: a single MDP (``jax.vmap`` over a stacked batch of equal shapes for many; MDPs of different sizes:
        :func:`hardness.measures_many`).
      gamma: discount of the continuous gaps, in ``(0, 1)`` (unused for episodic MDPs).
      variant: ``"paper"`` (exact values) or ``"colosseum"`` (the reference's value iteration).
      form: ``"regularized"`` (``sum 1 / (Delta + regularizer)``, the reference's) or ``"raw"`` (the paper's).
      regularizer: the ``0.1`` of the regularised form (positive).
      zero_tol: raw form: gaps up to ``zero_tol * max(1, max |V*|)`` count as zero.
      max_iter: sweep budget of the reference's value iteration.
    """
    check_variant(variant)
    if form not in ("regularized", "raw"):
        raise ValueError(f"form must be 'regularized' or 'raw'; got {form!r}")
    check_range("gamma", gamma, 0.0, 1.0, low_open=True, high_open=True)
    if not float(regularizer) > 0.0:
        raise ValueError(f"regularizer must be > 0; got {regularizer}")
    if not float(zero_tol) >= 0.0:
        raise ValueError(f"zero_tol must be >= 0; got {zero_tol}")
    dt = mdp.dtype
    return _sum_reciprocal_gaps(
        mdp.strip(),
        jnp.asarray(gamma, dt),
        jnp.asarray(regularizer, dt),
        jnp.asarray(zero_tol, dt),
        variant,
        form,
        int(max_iter),
    )
