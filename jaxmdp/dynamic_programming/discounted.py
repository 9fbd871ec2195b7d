"""Discounted dynamic programming (paper §2.1): ``Q(s,a) = R(s,a) + gamma * sum_s' P(s'|s,a) V(s')``.

Value iteration, exact policy evaluation and Howard's policy iteration on a model, and the discounted values of a
Markov reward chain: dense (one linear solve), banded (GTH elimination, :mod:`jaxmdp.gth`) and with deterministic
jumps eliminated. :func:`solve_discounted` gives ``Q*``, ``V*`` exact to floating-point precision.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import chex
import jax
import jax.numpy as jnp

from jaxmdp import struct
from jaxmdp._asserts import assert_chain, assert_model, assert_policy

from jaxmdp.dynamic_programming.backups import (
    Model,
    _action_mask,
    _masks,
    _rewards,
    compiled,
    greedy,
    policy_matrix,
    policy_rewards,
    q_values,
)
from jaxmdp.dynamic_programming.iteration import relative_value_iteration
from jaxmdp.dynamic_programming.markov_chains import _pass_down, _substitute_up
from jaxmdp.gth import BAND_BLOCK, gth_eliminate_banded
from jaxmdp.jaxlib_workarounds.linalg import solve as linear_solve

__all__ = [
    "ValueIterationResult",
    "value_iteration",
    "discounted_chain_values",
    "discounted_chain_values_banded",
    "discounted_banded_jump_chain_values",
    "discounted_jump_chain_values",
    "policy_evaluation",
    "policy_iteration_by",
    "policy_iteration",
    "solve_discounted",
]


class ValueIterationResult(struct.PyTreeNode):
    """Result of an iterative solver: values, iteration count and whether the stopping rule was met."""

    Q: jax.Array
    V: jax.Array
    iterations: jax.Array
    converged: jax.Array


@compiled()
def value_iteration(
    model: Model,
    gamma: float | jax.Array = 0.99,
    *,
    rewards: jax.Array | None = None,
    tol: float = 1e-4,
    max_iter: int = 100_000,
    V0: jax.Array | None = None,
) -> ValueIterationResult:
    """Synchronous (Jacobi) value iteration ``V <- max_a [R + gamma P V]`` from ``V0`` (default 0), for
    ``gamma < 1`` (:func:`~jaxmdp.dynamic_programming.relative_value_iteration` with the discounted rule).

    Stops when ``max_s |V_new - V| < tol`` (then ``||V_new - V*|| <= gamma tol / (1 - gamma)``) or after ``max_iter``
    sweeps, reported by ``converged``; ``V`` is ``V_new = max_a Q`` and ``Q`` the backup of the previous iterate.
    Use :func:`solve_discounted` for values exact to floating-point precision.
    """
    S, _ = assert_model(model, rewards)
    if V0 is not None:
        chex.assert_shape(V0, (S,), custom_message="V0: values [S]")
    R = _rewards(model, rewards)
    state_mask, action_mask = _masks(model, R)
    V0 = jnp.zeros(R.shape[:1], R.dtype) if V0 is None else V0
    res = relative_value_iteration(
        lambda V: q_values(model, V, gamma, R), V0, state_mask, action_mask, discount=gamma, tol=tol,
        max_iter=max_iter,
    )
    V = jnp.max(jnp.where(action_mask, res.Q, -jnp.inf), axis=-1)
    return ValueIterationResult(Q=res.Q, V=V, iterations=res.iterations, converged=res.converged)


def discounted_chain_values(P: jax.Array, r: jax.Array, gamma: float | jax.Array) -> jax.Array:
    """Discounted values ``V = (I - gamma P)^{-1} r`` of a Markov reward chain ``P[S, S]``, ``r[S]`` (Puterman 1994
    §6.1): one linear solve (:func:`jaxmdp.jaxlib_workarounds.linalg.solve`, one system at a time under ``vmap``)."""
    _assert_rewards(r, assert_chain(P), gamma)
    return linear_solve(jnp.eye(P.shape[0], dtype=P.dtype) - gamma * P, r)


def discounted_chain_values_banded(
    P: jax.Array, deficit: jax.Array, r: jax.Array, gamma: float | jax.Array, bandwidth: int,
    block: int = BAND_BLOCK,
) -> jax.Array:
    """:func:`discounted_chain_values` of a banded sub-stochastic chain: ``V = (I - gamma P)^{-1} r`` where ``P[i, j]
    = 0`` for ``|i - j| > bandwidth`` (static; not checked, see :func:`jaxmdp.gth.gth_eliminate_banded`) and
    ``deficit[s] = 1 - sum_j P[s, j] >= 0`` is given by the caller (exactly, e.g. the mass of a part of the kernel
    kept aside), so that no difference of nearly equal numbers is formed. ``r``: ``[S]`` or ``[S, m]`` (``m`` systems
    with one matrix).

    The discounted chain is a chain that stops with probability ``1 - gamma`` at each step, or leaves with the
    deficit: ``gamma P`` with ``out = (1 - gamma) + gamma deficit`` to an absorbing set. GTH elimination of it
    (:func:`jaxmdp.gth.gth_eliminate_banded`, last position first, ``O(S w (w + b))``) censors the chain to fewer and
    fewer states; eliminating ``k`` passes its reward on, ``r_i += col_k[i] r_k`` (``V_k = (r_k + sum_{j<k} M[k, j]
    V_j) / s_k`` substituted into the rows above), and back-substitution from position 0 gives ``V_k``. Every
    ``s_k >= 1 - gamma > 0``, and only non-negative numbers are added, as in the gain's elimination
    (:func:`~jaxmdp.dynamic_programming.chain_gain`)."""
    S = assert_chain(P)
    chex.assert_shape(deficit, (S,), custom_message="deficit: [S]")
    _assert_rewards(r, S, gamma)
    W = min(max(bandwidth, 1), S)
    gamma = jnp.asarray(gamma, P.dtype)  # 1 - gamma from the discount that multiplies P (0.999 is no float32)
    out = (1.0 - gamma) + gamma * deficit.astype(P.dtype)
    M, scale = gth_eliminate_banded(gamma * P, out, bandwidth, block)
    c = r if r.ndim == 2 else r[:, None]
    V = _substitute_up(M, scale, _pass_down(M, c.astype(P.dtype), W), jnp.zeros_like(c, P.dtype),
                       jnp.zeros((S,), bool), W)
    return V if r.ndim == 2 else V[:, 0]


def _slots(flags: jax.Array, size: int) -> tuple[jax.Array, jax.Array]:
    """The flagged states in ``size`` (static) slots: ``idx[size]``, the flagged states in order then ``S`` (an empty
    slot), and ``slot[S]``, each flagged state's slot (``size`` for the others and for flagged states past ``size``)."""
    S = flags.shape[0]
    (idx,) = jnp.nonzero(flags, size=size, fill_value=S)
    return idx, jnp.full((S,), size, jnp.int32).at[idx].set(jnp.arange(size, dtype=jnp.int32), mode="drop")


def discounted_banded_jump_chain_values(
    B: jax.Array, deficit: jax.Array, target: jax.Array, r: jax.Array, gamma: float | jax.Array, bandwidth: int,
    size: int, block: int = BAND_BLOCK,
) -> tuple[jax.Array, jax.Array]:
    """:func:`discounted_chain_values` of a chain whose row ``s`` is a banded part ``B[s]`` plus its missing mass
    ``deficit[s] = 1 - sum_j B[s, j]`` moved to one state ``target[s]``: ``P = B + D E_target``. Returns ``(V,
    fits)``.

    ``B[i, j] = 0`` for ``|i - j| > bandwidth`` (static; not checked), ``deficit`` exact as in
    :func:`discounted_chain_values_banded`. With ``T`` the states that receive some mass (``t_1 .. t_m``), ``P = B +
    W E^T``, ``W[s, j] = deficit[s] [target[s] = t_j]``, ``E = [e_{t_1} .. e_{t_m}]``. One banded elimination gives
    ``x, Y = (I - gamma B)^{-1} [r, W]`` (``O(S w (w + m))``), and Woodbury's identity ``V = x + gamma Y (I - gamma
    Y[T])^{-1} x[T]`` (``Y[T]``: the rows of ``T``) one ``m x m`` solve instead of an ``S x S`` one. ``I - gamma Y[T]``
    is an M-matrix: ``gamma Y 1 = 1 - (1 - gamma) (I - gamma B)^{-1} 1 <= gamma`` row by row. ``size`` (static)
    bounds ``m``; ``fits`` is False when ``m > size``, and ``V`` is then meaningless (solve otherwise)."""
    S = assert_chain(B)
    chex.assert_shape([deficit, target], (S,), custom_message="deficit and target: [S]")
    chex.assert_type(target, int, custom_message="target: state indices")
    chex.assert_rank(r, 1, custom_message="r: rewards [S]")
    dtype = B.dtype
    moves = deficit > 0
    is_target = jnp.zeros((S,), bool).at[jnp.where(moves, target, S)].set(True, mode="drop")
    idx, column = _slots(is_target, size)
    W = jnp.zeros((S, size + 1), dtype).at[jnp.arange(S), jnp.where(moves, column[target], size)].set(
        deficit.astype(dtype))[:, :size]
    X = discounted_chain_values_banded(B, deficit, jnp.concatenate([r[:, None].astype(dtype), W], axis=1), gamma,
                                       bandwidth, block)
    x, Y = X[:, 0], X[:, 1:]
    gamma = jnp.asarray(gamma, dtype)
    # Element-wise sums, not dot products: an accelerator may multiply float32 dot operands in reduced precision.
    w = linear_solve(jnp.eye(size, dtype=dtype) - gamma * Y.at[idx].get(mode="fill", fill_value=0.0),
                     x.at[idx].get(mode="fill", fill_value=0.0))
    return x + gamma * jnp.sum(Y * w, axis=1), jnp.sum(is_target) <= size


def discounted_jump_chain_values(
    P: jax.Array | Callable[[jax.Array], jax.Array], r: jax.Array, gamma: float | jax.Array, jump: jax.Array,
    size: int,
) -> tuple[jax.Array, jax.Array]:
    """:func:`discounted_chain_values` of a chain whose rows with ``jump[s] >= 0`` move deterministically to
    ``jump[s]`` (``P[s] = e_jump[s]``), by eliminating those states: ``(V, fits)``.

    With ``K`` the states with ``jump < 0`` and every state jumped to, a jumping state outside ``K`` has ``V_j = r_j +
    gamma V_jump[j]``, ``jump[j]`` in ``K``. Substituting it into the rows of ``K`` (Puterman 1994 §6.1's equations,
    restricted) leaves ``(I - gamma G) V_K = r_K + gamma P[K, ~K] r_~K`` with ``G[k, k'] = P[k, k'] + gamma sum_{j not
    in K, jump[j] = k'} P[k, j]``: one ``|K| x |K|`` solve and ``O(|K| S)`` work instead of an ``S x S`` solve.
    ``size`` (static) bounds ``|K|``; ``fits`` is False when ``|K| > size``, and ``V`` is then meaningless (solve
    the whole chain instead). Only the rows of ``K`` are read: ``P`` is the ``[S, S]`` chain or a function that
    returns its rows ``[n, S]`` at states ``[n]`` (so that a caller holding the chain in another form never builds
    it whole)."""
    chex.assert_rank(r, 1, custom_message="r: rewards [S]")
    S = r.shape[0]
    if not callable(P):
        chex.assert_shape(P, (S, S), custom_message="P: a chain [S, S]")
    chex.assert_shape(jump, (S,), custom_message="jump: [S]")
    chex.assert_type(jump, int, custom_message="jump: state indices")
    jumps = jump >= 0
    in_k = ~jumps | jnp.zeros((S,), bool).at[jnp.where(jumps, jump, S)].set(True, mode="drop")
    idx, pos = _slots(in_k, size)
    if callable(P):
        rows = jnp.where((idx < S)[:, None], P(jnp.minimum(idx, S - 1)), 0.0)
    else:
        rows = P.at[idx].get(mode="fill", fill_value=0.0)
    # V_j = r_j + gamma V_K[via[j]] for j outside K; column j of P[K] adds to column via[j] of G, gamma-weighted.
    via = jnp.where(in_k, pos, pos[jnp.maximum(jump, 0)])
    weight = jnp.where(in_k, 1.0, gamma).astype(rows.dtype)
    G = jax.ops.segment_sum((rows * weight).T, via, num_segments=size + 1).T[:, :size]
    rhs = r.at[idx].get(mode="fill", fill_value=0.0) + gamma * (rows @ jnp.where(in_k, 0.0, r))
    V_k = jnp.append(linear_solve(jnp.eye(size, dtype=rows.dtype) - gamma * G, rhs), 0.0)  # V_k[size]: empty slots
    return jnp.where(in_k, V_k[pos], r + gamma * V_k[via]), jnp.sum(in_k) <= size


def _assert_rewards(r: jax.Array, S: int, gamma: float | jax.Array) -> None:
    """``r`` is ``[S]`` or ``[S, m]`` floating and ``gamma`` a scalar (the chain solves)."""
    chex.assert_rank(r, {1, 2}, custom_message="r: rewards [S] or [S, m]")
    chex.assert_axis_dimension(r, 0, S, custom_message="r: rewards [S] or [S, m] of the chain's S states")
    chex.assert_type(r, float, custom_message="r: rewards")
    chex.assert_rank(gamma, 0, custom_message="gamma: a scalar discount")


def _policy_values(model: Model, pi: jax.Array, gamma: float | jax.Array, R: jax.Array) -> jax.Array:
    """``V = (I - gamma P_pi)^{-1} r_pi`` (the solve of :func:`policy_evaluation`)."""
    return discounted_chain_values(policy_matrix(model, pi), policy_rewards(model, pi, R), gamma)


def policy_evaluation(
    model: Model, pi: jax.Array, gamma: float | jax.Array = 0.99, rewards: jax.Array | None = None
) -> tuple[jax.Array, jax.Array]:
    """Exact discounted evaluation of a stationary policy: ``V = (I - gamma P_pi)^{-1} r_pi`` and its ``Q``.

    The solve is :func:`jaxmdp.jaxlib_workarounds.linalg.solve` (one system at a time under ``vmap``: jaxlib 0.10.2's
    batched CPU solve can deadlock)."""
    assert_policy(pi, *assert_model(model, rewards))
    R = _rewards(model, rewards)
    V = _policy_values(model, pi, gamma, R)
    return q_values(model, V, gamma, R), V


def policy_iteration_by(
    evaluate: Callable[[Any], jax.Array],
    improve: Callable[[Any, jax.Array], tuple[jax.Array, jax.Array, Any]],
    policy: Any,
    *,
    max_iter: int = 200,
    rtol: float = 1e-5,
) -> ValueIterationResult:
    """Howard's policy iteration on a model given by two functions, from ``policy`` (a pytree whose leaves all have
    the states on their leading axis, e.g. a one-hot ``[S, A]`` policy or a chosen kernel row per state).

    ``evaluate(policy) -> V[S]`` evaluates the policy exactly; ``improve(policy, V) -> (Q, gain[S], proposal)`` makes
    one backup of ``V`` (``Q``, returned as the result's ``Q``), the greedy ``proposal`` and, per state, ``gain = max_a
    Q(s, a) - Q(s, policy(s))``. A state switches to the proposal only when its gain exceeds ``eps = rtol * (1 +
    max|V|)``, so floating-point noise cannot make the loop cycle; it stops when no state switches (then ``V* - eps /
    (1 - gamma) <= V <= V*``) or after ``max_iter`` evaluations (``iterations`` counts them). :func:`policy_iteration`
    is this loop on a model's dense or successor-list backup; optimistic PSRL's extended MDP supplies a structured one
    (``agents.psrl_continuous``)."""
    chex.assert_equal_shape_prefix(jax.tree.leaves(policy), 1, custom_message="policy: leaves with the states first")

    def cond(c):
        return c[3] & (c[4] < max_iter)

    def body(c):
        pi, _, _, _, i = c
        V = evaluate(pi)
        Q, gain, proposal = improve(pi, V)
        switch = gain > rtol * (1.0 + jnp.max(jnp.abs(V)))
        new_pi = jax.tree.map(lambda b, p: jnp.where(switch.reshape(switch.shape + (1,) * (b.ndim - 1)), b, p),
                              proposal, pi)
        return new_pi, Q, V, jnp.any(switch), i + 1

    V_shape = jax.eval_shape(evaluate, policy)
    Q_shape = jax.eval_shape(lambda p, v: improve(p, v)[0], policy, V_shape)
    init = (policy, jnp.zeros(Q_shape.shape, Q_shape.dtype), jnp.zeros(V_shape.shape, V_shape.dtype),
            jnp.asarray(True), jnp.asarray(0))
    _, Q, V, changed, it = jax.lax.while_loop(cond, body, init)
    return ValueIterationResult(Q=Q, V=V, iterations=it, converged=~changed)


@compiled()
def policy_iteration(
    model: Model,
    gamma: float | jax.Array = 0.99,
    *,
    rewards: jax.Array | None = None,
    policy: jax.Array | None = None,
    max_iter: int = 200,
    rtol: float = 1e-5,
) -> ValueIterationResult:
    """Howard's policy iteration with exact (linear-solve) evaluation, from ``policy`` (default: greedy on ``R``).

    An action is replaced only when another improves its ``Q`` by more than ``eps = rtol * (1 + max|V|)``, so
    floating-point noise cannot make it cycle. The final policy is then within ``eps`` of greedy, so
    ``V* - eps / (1 - gamma) <= V <= V*`` (a bound met only when actions are nearly tied). ``Q``/``V`` are those of
    the final policy; ``iterations`` counts evaluations. (:func:`policy_iteration_by` with the model's backup.)
    """
    S, A = assert_model(model, rewards)
    if policy is not None:
        assert_policy(policy, S, A, "policy")
    R = _rewards(model, rewards)
    mask = _action_mask(model)
    pi0 = greedy(R, mask) if policy is None else policy

    def improve(pi, V):
        Q = q_values(model, V, gamma, R)
        cur = jnp.sum(pi * Q, axis=-1)
        gain = jnp.max(jnp.where(mask, Q, -jnp.inf) if mask is not None else Q, axis=-1) - cur
        return Q, gain, greedy(Q, mask)

    return policy_iteration_by(lambda pi: _policy_values(model, pi, gamma, R), improve, pi0, max_iter=max_iter,
                               rtol=rtol)


@compiled()
def solve_discounted(
    model: Model, gamma: float | jax.Array = 0.99, *, rewards: jax.Array | None = None, vi_tol: float = 1e-3
) -> ValueIterationResult:
    """Optimal discounted ``Q*``, ``V*`` exact to floating-point precision.

    A coarse value iteration (``vi_tol``) finds a near-optimal greedy policy, and policy iteration with exact
    evaluation finishes the job (usually in one or two linear solves).
    """
    assert_model(model, rewards)
    R = _rewards(model, rewards)
    vi = value_iteration(model, gamma, rewards=R, tol=vi_tol, max_iter=10_000)
    return policy_iteration(model, gamma, rewards=R, policy=greedy(vi.Q, _action_mask(model)))


# ---------------------------------------------------------------------------------------------------------------
# Finite horizon
# ---------------------------------------------------------------------------------------------------------------
