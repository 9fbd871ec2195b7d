"""The mixing time of a policy's Markov chain (a measure the paper lists as not known to be computable, Table 1).

For a stationary policy ``pi`` of a continuous MDP with state-to-state kernel ``P = P_pi`` and Cesàro limit
``P* = lim_n (1/n) sum_{t<n} P^t`` (:func:`jaxmdp.occupancy.cesaro_limit`), the distance to stationarity after ``t`` steps is
``d(t) = max_s TV(P^t(s, .), P*(s, .))`` with ``TV(p, q) = (1/2) sum_s' |p(s') - q(s')|``, and

    ``t_mix(eps) = min {t >= 0 : d(t) <= eps}``   (Levin, Peres & Wilmer, *Markov Chains and Mixing Times*, §4.5).

For an irreducible chain ``P*(s, .)`` is the stationary distribution and this is the textbook definition. For a
multichain policy ``P*(s, .)`` is the long-run distribution from ``s`` (a mixture of the closed classes' stationary
distributions), so ``t_mix`` is how long every start takes to forget where in its class it began. ``d`` never
increases (``P P* = P*`` gives ``|P^{t+1}(s,.) - P*(s,.)| <= sum_u P(s,u) |P^t(u,.) - P*(u,.)|``), so ``t_mix`` is
found exactly by doubling then bisection on matrix powers: ``O(S^3 log t_mix)``.

Periodic chains: a chain with a closed class of period ``p > 1`` keeps ``d(t) >= 1 - 1/p >= 1/2`` for ever (``P^t``
puts all of the class's mass on one cyclic sub-class), so for ``eps < 1/2`` it never mixes and the result is ``inf``
(with ``converged=False``: the doubling budget ran out, which is also what a chain too slow for the budget gives).
``lazy=True`` measures the lazy chain ``(I + P) / 2`` instead (same ``P*``, always aperiodic), the usual remedy.

Episodic MDPs have no mixing time worth the name: every episode restarts from ``P0`` after ``H`` steps whatever
happened, so the time-augmented chain forgets its start exactly within ``H`` steps and is periodic with period ``H``;
:func:`mixing_time` refuses them.
"""

from __future__ import annotations

import functools

import chex
import jax
import jax.numpy as jnp

from hardness.result import MeasureResult
from jaxmdp import dynamic_programming as dp
from jaxmdp._asserts import assert_chain, assert_mdp, assert_policy
from jaxmdp._checks import check_int, check_range
from jaxmdp.mdp import MDP
from jaxmdp.occupancy import cesaro_limit
from jaxmdp.values import optimal_policy

__all__ = ["mixing_time", "chain_mixing_time", "policy_check"]


def _distance(M: jax.Array, Pstar: jax.Array, state_mask: jax.Array) -> jax.Array:
    """``max_s TV(M(s, .), P*(s, .))`` over the real states."""
    tv = 0.5 * jnp.sum(jnp.abs(M - Pstar), axis=1)
    return jnp.max(jnp.where(state_mask, tv, 0.0))


@functools.partial(jax.jit, static_argnames=("max_doublings",))
def chain_mixing_time(
    P: jax.Array, eps: float | jax.Array = 0.25, state_mask: jax.Array | None = None, max_doublings: int = 30
) -> MeasureResult:
    """``t_mix(eps)`` of a stochastic matrix ``P[S, S]`` (module docstring), exact, as a :class:`MeasureResult`.

    ``P^(2^k)`` is squared until ``d(2^k) <= eps`` (at most ``max_doublings`` squarings, else ``inf`` with
    ``converged=False``); the answer in ``(2^(k-1), 2^k]`` is then found by bisection with the stored powers. Only the
    states of ``state_mask`` (default all) are starts. Jittable; vmaps over a batch of matrices.
    """
    S = assert_chain(P)
    chex.assert_rank(eps, 0, custom_message="eps: a scalar threshold")
    if state_mask is not None:
        chex.assert_shape(state_mask, (S,), custom_message="state_mask: [S]")
    dtype = P.dtype
    mask = jnp.ones((S,), bool) if state_mask is None else state_mask
    eps = jnp.asarray(eps, dtype)
    Pstar = cesaro_limit(P)
    K = max_doublings + 1

    def square(k, carry):
        powers, M = carry
        powers = powers.at[k].set(M)
        M = M @ M
        return powers, M / jnp.sum(M, axis=1, keepdims=True)

    powers, _ = jax.lax.fori_loop(0, K, square, (jnp.zeros((K, S, S), dtype), P))
    dist = jax.vmap(lambda M: _distance(M, Pstar, mask))(powers)  # d(2^k), non-increasing in k
    d0 = _distance(jnp.eye(S, dtype=dtype), Pstar, mask)
    ok = dist <= eps
    k = jnp.argmax(ok)  # first doubling that mixes
    found = jnp.any(ok)

    # Bisection: the largest t < 2^k with d(t) > eps, built bit by bit from 2^(k-1) downwards; t_mix is t + 1.
    def bit(i, carry):
        j = K - 1 - i
        t, M = carry
        cand = M @ powers[j]
        take = (j <= k - 2) & (_distance(cand, Pstar, mask) > eps)
        return jnp.where(take, t + jnp.left_shift(1, j), t), jnp.where(take, cand, M)

    start = jnp.where(k >= 1, powers[jnp.maximum(k - 1, 0)], jnp.eye(S, dtype=dtype))
    t0 = jnp.where(k >= 1, jnp.left_shift(1, jnp.maximum(k - 1, 0)), 0).astype(jnp.int32)
    t, _ = jax.lax.fori_loop(0, K, bit, (t0, start))
    value = jnp.where(d0 <= eps, 0, t + 1).astype(dtype)
    return MeasureResult.make(value, found | (d0 <= eps))


def policy_check(mdp: MDP, policy: jax.Array | None, name: str = "policy", *, time_indexed: bool = False) -> None:
    """Raise ``ValueError`` unless ``policy`` is ``None`` or a policy of ``mdp``: ``[S, A]``, or with
    ``time_indexed`` and an episodic MDP also ``[H, S, A]``."""
    if policy is None:
        return
    S, A = mdp.n_states, mdp.n_actions
    shapes = [(S, A)] + ([(mdp.H, S, A)] if time_indexed and mdp.episodic else [])
    if tuple(jnp.shape(policy)) not in shapes:
        raise ValueError(f"{name} must be a policy of shape {' or '.join(map(str, shapes))}; got {jnp.shape(policy)}")


def mixing_time(
    mdp: MDP,
    policy: jax.Array | None = None,
    eps: float = 0.25,
    *,
    lazy: bool = False,
    max_doublings: int = 30,
) -> MeasureResult:
    """Mixing time ``t_mix(eps)`` of ``policy``'s chain on a continuous MDP (module docstring; Levin, Peres &
    Wilmer 2017, §4.5).

    Args:
      mdp: a continuous MDP (a stacked batch under ``jax.vmap``; padded states are never starts).
      policy: ``pi[S, A]``; default the gain-optimal policy (:func:`jaxmdp.values.optimal_policy`).
      eps: the TV threshold, in ``(0, 1)``; 1/4 is the textbook ``t_mix``.
      lazy: measure the lazy chain ``(I + P_pi) / 2`` (aperiodic) instead of ``P_pi``.
      max_doublings: budget, at most 30: chains that have not mixed after ``2^max_doublings`` steps give ``inf``
        with ``converged=False`` (as does a periodic chain with ``eps < 1/2``).

    Returns:
      a :class:`MeasureResult` whose ``value`` is ``t_mix`` in steps (an integer held as a float).

    Raises:
      ValueError: for an episodic MDP, a policy of the wrong shape, or ``eps`` outside ``(0, 1)``.
    """
    if mdp.episodic:
        raise ValueError(
            "mixing_time needs a continuous MDP: an episodic MDP restarts from P0 every H steps, so its time-augmented "
            "chain forgets its start within H steps and is periodic with period H (hardness.mixing docstring)"
        )
    check_range("eps", eps, 0.0, 1.0, low_open=True, high_open=True)
    max_doublings = check_int("max_doublings", max_doublings, 1, 30)
    policy_check(mdp, policy)
    return _mixing_time(mdp.strip(), policy, jnp.asarray(eps, mdp.dtype), lazy, max_doublings)


@functools.partial(jax.jit, static_argnames=("lazy", "max_doublings"))
def _mixing_time(mdp: MDP, policy, eps, lazy, max_doublings):
    S, A = assert_mdp(mdp)
    if policy is not None:
        assert_policy(policy, S, A, "policy")
    pi = optimal_policy(mdp) if policy is None else policy.astype(mdp.dtype)
    P = dp.policy_matrix(mdp, pi)
    if lazy:
        P = 0.5 * (jnp.eye(P.shape[0], dtype=P.dtype) + P)
    return chain_mixing_time(P, eps, mdp.state_mask, max_doublings)
