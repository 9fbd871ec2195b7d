"""The distribution mismatch coefficient (a measure the paper lists as not known to be computable, Table 1).

Kakade & Langford (2002, "Approximately optimal approximate reinforcement learning", §4 and Thm. 6.2) and Agarwal,
Kakade, Lee & Mahajan (2021, "On the theory of policy gradient methods", JMLR 22, Def. 3.1 and §5) measure how well
a distribution ``mu`` covers the states that a policy ``pi`` visits by

    ``C(pi, mu) = || d^pi / mu ||_inf = max_s d^pi(s) / mu(s)``   (``0 / 0 = 0``, ``x / 0 = inf`` for ``x > 0``),

where ``d^pi`` is the state-visitation distribution of ``pi`` from the MDP's start distribution ``P0``. ``C >= 1``
whenever ``mu`` is a distribution (both sum to one), ``C = 1`` iff ``mu = d^pi``, and ``C = inf`` when ``pi`` visits a
state that ``mu`` never puts mass on. Which visitation distribution ``d^pi``:

* continuous MDP, ``gamma`` given (Agarwal et al.'s definition): the discounted visitation
  ``d^pi(s) = (1 - gamma) sum_t gamma^t Pr(s_t = s | s_0 ~ P0, pi)``, i.e. ``d^T = (1 - gamma) P0^T (I - gamma P_pi)^-1``;
* continuous MDP, ``gamma=None`` (default; the average-reward counterpart): the long-run distribution
  ``d^T = P0^T P*_pi`` (``P*_pi`` the Cesàro limit; the stationary distribution of a unichain policy);
* episodic MDP with horizon ``H`` (the finite-horizon version, Kakade 2003, PhD thesis §2.1): the average
  in-episode distribution ``d^pi(s) = (1/H) sum_{h<H} Pr(s_h = s | s_0 ~ P0, pi)``, ``pi`` stationary or
  time-indexed.

``reference`` is either a distribution ``mu[S]`` (a start or exploration distribution, as in both papers) or a
policy, whose visitation distribution (computed the same way) is then ``mu``: ``C(pi, pi) = 1``. The distributions
are those of :func:`jaxmdp.occupancy.state_distribution`.
"""

from __future__ import annotations

import functools

import chex
import jax
import jax.numpy as jnp

from hardness.mixing import policy_check
from hardness.result import MeasureResult
from jaxmdp._asserts import assert_mdp, assert_policy
from jaxmdp._checks import check_range
from jaxmdp.mdp import MDP
from jaxmdp.occupancy import state_distribution
from jaxmdp.values import optimal_policy

__all__ = ["distribution_mismatch", "mismatch_ratio"]


def distribution_mismatch(
    mdp: MDP,
    policy: jax.Array | None,
    reference: jax.Array,
    *,
    gamma: float | None = None,
) -> MeasureResult:
    """Distribution mismatch coefficient ``max_s d^pi(s) / mu(s)`` (module docstring; Kakade & Langford 2002,
    Agarwal et al. 2021 Def. 3.1).

    Args:
      mdp: one MDP (``jax.vmap`` over a stacked batch; padded states have no mass on either side).
      policy: ``pi[S, A]`` (or ``[H, S, A]`` for an episodic MDP); ``None``: the optimal policy
        (:func:`jaxmdp.values.optimal_policy`).
      reference: a distribution ``mu[S]`` over states, or a policy (same shapes as ``policy``) whose visitation
        distribution is ``mu``.
      gamma: continuous MDPs only: the discount of the visitation distribution, in ``(0, 1)``; ``None`` (default)
        uses the long-run distribution.

    Returns:
      a :class:`MeasureResult`: ``value`` ``>= 1`` up to round-off, ``inf`` where ``pi`` visits a state ``mu``
      misses (``converged`` is always True: the computation is exact). With ``gamma``, masses below ``1e-6`` of the
      largest are taken as zero (the linear solve's round-off).

    Raises:
      ValueError: for shapes that fit neither a policy nor a distribution, ``gamma`` with an episodic MDP or outside
      ``(0, 1)``.
    """
    policy_check(mdp, policy, "policy", time_indexed=True)
    ref_is_policy = jnp.ndim(reference) >= 2
    if ref_is_policy:
        policy_check(mdp, reference, "reference", time_indexed=True)
    elif tuple(jnp.shape(reference)) != (mdp.n_states,):
        raise ValueError(
            f"reference must be a distribution of shape ({mdp.n_states},) or a policy of shape "
            f"({mdp.n_states}, {mdp.n_actions}); got {jnp.shape(reference)}"
        )
    if gamma is not None:
        if mdp.episodic:
            raise ValueError("gamma must be None for an episodic MDP (its visitation distribution is the in-episode "
                             "average)")
        check_range("gamma", gamma, 0.0, 1.0, low_open=True, high_open=True)
        gamma = jnp.asarray(gamma, mdp.dtype)
    return _distribution_mismatch(mdp.strip(), policy, jnp.asarray(reference, mdp.dtype), gamma, ref_is_policy)


@functools.partial(jax.jit, static_argnames=("ref_is_policy",))
def _distribution_mismatch(mdp: MDP, policy, reference, gamma, ref_is_policy):
    S, A = assert_mdp(mdp)
    if policy is not None:
        assert_policy(policy, S, A, "policy", time_indexed=mdp.episodic)
    if ref_is_policy:
        assert_policy(reference, S, A, "reference", time_indexed=mdp.episodic)
    else:
        chex.assert_shape(reference, (S,), custom_message="reference: a distribution [S]")
    pi = optimal_policy(mdp) if policy is None else policy.astype(mdp.dtype)
    d = state_distribution(mdp, pi, gamma)
    mu = state_distribution(mdp, reference, gamma) if ref_is_policy else reference
    # Forward propagation (episodic) and the Cesàro limit's squarings keep exact zeros where the mass is zero (a
    # transient state's mass underflows to 0 within the 2^48 steps); the discounted linear solve leaves round-off of
    # relative size ~1e-7 there, so its masses below 1e-6 of the largest count as zero.
    rel_tol = 1e-6 if gamma is not None else 0.0
    return MeasureResult.make(mismatch_ratio(d, mu, mdp.state_mask, rel_tol), True)


def mismatch_ratio(
    d: jax.Array, mu: jax.Array, state_mask: jax.Array | None = None, rel_tol: float = 0.0
) -> jax.Array:
    """``max_s d(s) / mu(s)`` with ``0 / 0 = 0`` and ``x / 0 = inf``, over ``state_mask`` (default all states).
    Masses at most ``rel_tol`` times the largest count as zero (round-off where the exact mass is zero)."""
    chex.assert_rank(d, 1, custom_message="d: a distribution [S]")
    chex.assert_equal_shape([d, mu], custom_message="d and mu: distributions [S]")
    chex.assert_type([d, mu], float, custom_message="d and mu: distributions")
    if state_mask is not None:
        chex.assert_shape(state_mask, d.shape, custom_message="state_mask: [S]")
    d = jnp.where(d > rel_tol * jnp.max(d), d, 0.0)
    mu_pos = mu > rel_tol * jnp.max(mu)
    ratio = jnp.where(mu_pos, d / jnp.where(mu_pos, mu, 1.0), jnp.where(d > 0, jnp.inf, 0.0))
    if state_mask is not None:
        ratio = jnp.where(state_mask, ratio, 0.0)
    return jnp.max(ratio)
