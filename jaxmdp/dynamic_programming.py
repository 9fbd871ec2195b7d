"""Dynamic programming on MDPs: discounted, finite-horizon and average-reward, all jittable and vmappable.

Every routine works on one *model* and leaves batching to ``jax.vmap``. A model is either an :class:`~jaxmdp.MDP`
(expectations then use its successor lists, ``O(S A K)`` per backup) or a dense ``[S, A, S]`` kernel (used by agents
that plan on sampled or estimated kernels). Rewards default to the MDP's ``R`` and can be overridden, e.g. with
``-R`` for the worst policy or with an estimate.

Conventions (paper §2.1):

* discounted: ``Q(s,a) = R(s,a) + gamma * sum_s' P(s'|s,a) V(s')``;
* finite horizon ``H``: ``V_H = 0``, ``Q_h = R + P V_{h+1}``, ``V_h = max_a Q_h`` for ``h = H-1..0``; arrays carry
  ``H`` time rows for ``Q`` and ``H + 1`` for ``V`` (row ``H`` is zero). A traced ``horizon <= H`` makes the steps
  ``h >= horizon`` worth zero, so stacked MDPs of different horizons share one program;
* average reward: the gain of a policy from a start distribution ``d`` is ``rho = d^T P*_pi r_pi`` with ``P*_pi``
  the Cesàro limit of the policy's chain. This is the paper's ``<mu^pi, R^pi>`` when the chain has one recurrent
  class, and its natural extension (the expected long-run average reward from ``d``) otherwise.

Greedy policies break ties deterministically towards the lowest action index.

One iterative loop serves the value iterations here and in the agents: :func:`relative_value_iteration` iterates a
Bellman backup given as a function ``backup(u) -> Q[S, A]``, so the same loop solves an ordinary MDP
(:func:`value_iteration`), UCRL2's extended MDP (the backup maximises over a confidence set of kernels) and
optimistic PSRL's extended MDP (the backup maximises over sampled kernels). :func:`optimal_gain` runs the same
iteration with arithmetic of its own, for its tighter tolerance (see there).

The routines with loops are jitted (:func:`compiled`), so that eager calls compile once per shape; the loops that take
a backup function (:func:`relative_value_iteration`, :func:`policy_iteration_by`) are meant to be called inside the
caller's ``jit``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from jaxmdp.gth import BAND_BLOCK, GTH_BLOCK, gth_eliminate, gth_eliminate_banded
from jaxmdp.gth import bandwidth as gth_bandwidth
from jaxmdp.jaxlib_workarounds.linalg import solve as linear_solve
from jaxmdp.mdp import MDP

Model = MDP | jax.Array


def compiled(*static_argnames: str) -> Callable[[Callable], Callable]:
    """Decorator: the routine jitted (``static_argnames`` static), its :class:`~jaxmdp.MDP` arguments stripped of their
    static metadata (:meth:`~jaxmdp.MDP.strip`) first.

    An eager call then compiles once per shape, and MDPs of one shape share the program whatever their labels. A
    routine with a loop called eagerly without ``jit`` compiled its loop again at every call (the loop body is a new
    closure each time: 0.3-1 s per call on the 2-core CPU, docs/testing.md "Suite time"). Inside another ``jit`` the
    routine is inlined as before."""

    def wrap(fun: Callable) -> Callable:
        jitted = jax.jit(fun, static_argnames=static_argnames)
        strip = lambda x: x.strip() if isinstance(x, MDP) else x  # noqa: E731

        @functools.wraps(fun)
        def call(*args: Any, **kwargs: Any) -> Any:
            return jitted(*map(strip, args), **{k: strip(v) for k, v in kwargs.items()})

        call.jitted = jitted  # the jitted routine itself (e.g. ``.lower``)
        return call

    return wrap


# Up to this many actions greedy() unrolls its passes over the action axis (see there).
_UNROLLED_GREEDY_MAX_ACTIONS = 16

__all__ = [
    "discounted_jump_chain_values",
    "expected_next_values",
    "q_values",
    "greedy",
    "greedy_actions",
    "uniform_policy",
    "policy_matrix",
    "policy_rewards",
    "PlanResult",
    "relative_value_iteration",
    "ValueIterationResult",
    "value_iteration",
    "policy_evaluation",
    "policy_iteration",
    "policy_iteration_by",
    "discounted_chain_values",
    "discounted_chain_values_banded",
    "solve_discounted",
    "finite_horizon_value_iteration",
    "finite_horizon_policy_evaluation",
    "finite_horizon_deterministic_evaluation",
    "finite_horizon_start_values",
    "finite_horizon_deterministic_start_values",
    "successor_rows",
    "recurrent_classes",
    "successor_reachability",
    "chain_gain",
    "chain_bias",
    "cesaro_limit",
    "successor_policy_matrix",
    "gain_vector",
    "GainBounds",
    "policy_successor_lists",
    "successor_gain_bounds",
    "policy_gain",
    "GainResult",
    "optimal_gain",
]


# ---------------------------------------------------------------------------------------------------------------
# Building blocks
# ---------------------------------------------------------------------------------------------------------------


def _dense(model: Model) -> jax.Array:
    return model.T if isinstance(model, MDP) else model


def _rewards(model: Model, rewards: jax.Array | None) -> jax.Array:
    if rewards is not None:
        return rewards
    if isinstance(model, MDP):
        return model.R
    raise ValueError("rewards must be given when the model is a dense kernel")


def _action_mask(model: Model) -> jax.Array | None:
    return model.action_mask if isinstance(model, MDP) else None


def _masks(model: Model, R: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The real states and actions of ``model``: its masks, or all of them for a dense kernel."""
    if isinstance(model, MDP):
        return model.state_mask, model.action_mask
    return jnp.ones(R.shape[:1], bool), jnp.ones(R.shape[1:], bool)


def expected_next_values(model: Model, V: jax.Array) -> jax.Array:
    """``E[V(s') | s, a] = sum_s' P(s'|s,a) V(s')`` for every ``(s, a)``: an ``[S, A]`` array."""
    if isinstance(model, MDP):
        return jnp.sum(model.succ_p * V[model.succ], axis=-1)
    return jnp.einsum("sat,t->sa", model, V)


def q_values(model: Model, V: jax.Array, gamma: float | jax.Array = 1.0, rewards: jax.Array | None = None) -> jax.Array:
    """One Bellman backup: ``Q = R + gamma * P V``."""
    return _rewards(model, rewards) + gamma * expected_next_values(model, V)


def greedy_actions(Q: jax.Array, action_mask: jax.Array | None = None, atol: float = 0.0) -> jax.Array:
    """The greedy action of every row of ``Q[..., A]`` as an ``int32`` index: the lowest index within ``atol`` of the
    row's maximum, padded actions (``action_mask``) excluded. :func:`greedy` is its one-hot form."""
    if action_mask is not None:
        Q = jnp.where(action_mask, Q, -jnp.inf)
    A = Q.shape[-1]
    if A > _UNROLLED_GREEDY_MAX_ACTIONS:
        best = jnp.max(Q, axis=-1, keepdims=True)
        return jnp.argmax(Q >= best - atol, axis=-1).astype(jnp.int32)
    # Few actions: elementwise passes over the action axis. XLA runs the variadic argmax reduction several times
    # slower on CPU, and a lockstep run evaluates a greedy policy for every member at every log.
    best = Q[..., 0]
    for a in range(1, A):
        best = jnp.maximum(best, Q[..., a])
    index = jnp.zeros(Q.shape[:-1], jnp.int32)
    for a in reversed(range(A)):
        index = jnp.where(Q[..., a] >= best - atol, a, index)
    return index


def greedy(Q: jax.Array, action_mask: jax.Array | None = None, atol: float = 0.0) -> jax.Array:
    """One-hot greedy policy of ``Q[..., A]``.

    Actions within ``atol`` of the maximum count as tied and the lowest index wins. ``action_mask`` excludes padded
    actions.
    """
    return jax.nn.one_hot(greedy_actions(Q, action_mask, atol), Q.shape[-1], dtype=Q.dtype)


def uniform_policy(model: Model, shape: tuple[int, ...] = ()) -> jax.Array:
    """The uniformly random policy ``pi(a|s) = 1/|A|`` over the valid actions, shape ``[*shape, S, A]``."""
    T = _dense(model)
    S, A = T.shape[0], T.shape[1]
    mask = _action_mask(model)
    w = jnp.ones((A,), T.dtype) if mask is None else mask.astype(T.dtype)
    return jnp.broadcast_to(w / jnp.sum(w), (*shape, S, A))


def policy_matrix(model: Model, pi: jax.Array) -> jax.Array:
    """State-to-state kernel ``P_pi[s, s'] = sum_a pi(a|s) P(s'|s,a)`` of a stationary policy ``pi[S, A]``."""
    return jnp.einsum("sa,sat->st", pi, _dense(model))


def policy_rewards(model: Model, pi: jax.Array, rewards: jax.Array | None = None) -> jax.Array:
    """Expected one-step reward ``r_pi(s) = sum_a pi(a|s) R(s,a)``."""
    return jnp.sum(pi * _rewards(model, rewards), axis=-1)


# ---------------------------------------------------------------------------------------------------------------
# The value-iteration loop
# ---------------------------------------------------------------------------------------------------------------
#
# Average reward (``discount == 1``; Puterman 1994 §8.5, Jaksch et al. 2010 §3.1.2): with ``T u = max_a backup(u)``
# and ``d = T u - u``, every iterate satisfies ``min_s d(s) <= rho* <= max_s d(s)`` and a policy greedy on
# ``backup(u)`` is ``span(d)``-optimal, so the loop stops when ``span(d) < tol``. Each step moves
# ``u <- u + tau d`` (``tau = aperiodicity``), which is value iteration on the aperiodic transform
# ``P_tau = tau P + (1 - tau) I``: it has the same gains and optimal policies, and makes the loop converge also when
# the optimal chains are periodic (deterministic cycles, where plain value iteration oscillates for ever). ``u`` is
# shifted so that its minimum over real states is 0, which keeps it bounded.
#
# Discounted (``discount < 1``): plain value iteration, stopped when ``max_s |d(s)| < tol``; the caller's ``backup``
# applies the discount.


class PlanResult(struct.PyTreeNode):
    """Result of :func:`relative_value_iteration`.

    ``Q = backup(u)`` at the returned ``u``; ``gain_lower``/``gain_upper`` are ``min``/``max`` of ``T u - u`` over
    the real states (bounds on the optimal gain when ``discount == 1``); ``converged`` tells whether the stopping
    rule was met within ``max_iter`` sweeps.
    """

    Q: jax.Array
    u: jax.Array
    gain_lower: jax.Array
    gain_upper: jax.Array
    iterations: jax.Array
    converged: jax.Array


def relative_value_iteration(
    backup: Callable[[jax.Array], jax.Array],
    u0: jax.Array,
    state_mask: jax.Array,
    action_mask: jax.Array,
    *,
    discount: float | jax.Array = 1.0,
    tol: float | jax.Array = 1e-3,
    max_iter: int = 100_000,
    aperiodicity: float | jax.Array = 0.5,
    active: bool | jax.Array = True,
) -> PlanResult:
    """Iterate ``u <- u + step * (max_a backup(u) - u)`` from ``u0`` until the stopping rule of the section comment
    above (``step`` is ``aperiodicity`` for average reward, 1 when discounted).

    Padded actions (``action_mask``) are excluded from the maximum; padded states (``state_mask``) from the stopping
    rule and the normalisation. ``discount`` may be traced (1 selects the average-reward rule, ``< 1`` the discounted
    one), so a hyperparameter grid can mix both. ``active = False`` skips the loop (the result is then meaningless):
    under ``vmap`` a batched ``while_loop`` runs until its last member stops, so members whose result will be
    discarded should not keep it going.
    """
    dtype = u0.dtype
    average = jnp.asarray(discount) >= 1.0
    step = jnp.where(average, jnp.asarray(aperiodicity, dtype), jnp.asarray(1.0, dtype))
    inf = jnp.asarray(jnp.inf, dtype)

    def sweep(u):
        Q = backup(u)
        d = jnp.max(jnp.where(action_mask, Q, -inf), axis=-1) - u
        lo = jnp.min(jnp.where(state_mask, d, inf))
        hi = jnp.max(jnp.where(state_mask, d, -inf))
        err = jnp.where(average, hi - lo, jnp.maximum(hi, -lo))
        return Q, d, lo, hi, err

    def cond(c):
        *_, err, i = c
        return (err >= tol) & (i < max_iter) & active

    def body(c):
        u, *_, i = c
        Q, d, lo, hi, err = sweep(u)
        u_next = u + step * d
        u_next = jnp.where(average, u_next - jnp.min(jnp.where(state_mask, u_next, inf)), u_next)
        # Keep the ``u`` that produced ``Q`` when the rule is met, so the result is self-consistent.
        u_next = jnp.where(err < tol, u, u_next)
        return u_next, Q, lo, hi, err, i + 1

    S, A = u0.shape[0], action_mask.shape[-1]
    init = (u0, jnp.zeros((S, A), dtype), -inf, inf, inf, jnp.asarray(0, jnp.int32))
    u, Q, lo, hi, err, it = jax.lax.while_loop(cond, body, init)
    return PlanResult(Q=Q, u=u, gain_lower=lo, gain_upper=hi, iterations=it, converged=err < tol)


# ---------------------------------------------------------------------------------------------------------------
# Discounted
# ---------------------------------------------------------------------------------------------------------------


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
    ``gamma < 1`` (:func:`relative_value_iteration` with the discounted rule).

    Stops when ``max_s |V_new - V| < tol`` (then ``||V_new - V*|| <= gamma tol / (1 - gamma)``) or after ``max_iter``
    sweeps, reported by ``converged``; ``V`` is ``V_new = max_a Q`` and ``Q`` the backup of the previous iterate.
    Use :func:`solve_discounted` for values exact to floating-point precision.
    """
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
    return linear_solve(jnp.eye(P.shape[0], dtype=P.dtype) - gamma * P, r)


def discounted_chain_values_banded(
    P: jax.Array, deficit: jax.Array, r: jax.Array, gamma: float | jax.Array, bandwidth: int,
    block: int = BAND_BLOCK,
) -> jax.Array:
    """:func:`discounted_chain_values` of a banded sub-stochastic chain: ``V = (I - gamma P)^{-1} r`` where ``P[i, j]
    = 0`` for ``|i - j| > bandwidth`` (static; not checked, see :func:`jaxmdp.gth.gth_eliminate_banded`) and
    ``deficit[s] = 1 - sum_j P[s, j] >= 0`` is given by the caller (exactly, e.g. the mass of a part of the kernel
    kept aside), so that no difference of nearly equal numbers is formed. ``r``: ``[S]`` or ``[S, m]`` (``m`` systems with one matrix).

    The discounted chain is a chain that stops with probability ``1 - gamma`` at each step, or leaves with the
    deficit: ``gamma P`` with ``out = (1 - gamma) + gamma deficit`` to an absorbing set. GTH elimination of it
    (:func:`jaxmdp.gth.gth_eliminate_banded`, last position first, ``O(S w (w + b))``) censors the chain to fewer and
    fewer states; eliminating ``k`` passes its reward on, ``r_i += col_k[i] r_k`` (``V_k = (r_k + sum_{j<k} M[k, j]
    V_j) / s_k`` substituted into the rows above), and back-substitution from position 0 gives ``V_k``. Every
    ``s_k >= 1 - gamma > 0``, and only non-negative numbers are added, as in the gain's elimination
    (:func:`chain_gain`)."""
    S = P.shape[0]
    W = min(max(bandwidth, 1), S)
    gamma = jnp.asarray(gamma, P.dtype)  # 1 - gamma from the discount that multiplies P (0.999 is no float32)
    out = (1.0 - gamma) + gamma * deficit.astype(P.dtype)
    M, scale = gth_eliminate_banded(gamma * P, out, bandwidth, block)
    c = r if r.ndim == 2 else r[:, None]
    V = _substitute_up(M, scale, _pass_down(M, c.astype(P.dtype), W), jnp.zeros_like(c, P.dtype),
                       jnp.zeros((S,), bool), W)
    return V if r.ndim == 2 else V[:, 0]


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
    S = r.shape[0]
    jumps = jump >= 0
    in_k = ~jumps | jnp.zeros((S,), bool).at[jnp.where(jumps, jump, S)].set(True, mode="drop")
    (idx,) = jnp.nonzero(in_k, size=size, fill_value=S)  # K's states, then S (an empty slot)
    pos = jnp.full((S,), size, jnp.int32).at[idx].set(jnp.arange(size, dtype=jnp.int32), mode="drop")
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


def _policy_values(model: Model, pi: jax.Array, gamma: float | jax.Array, R: jax.Array) -> jax.Array:
    """``V = (I - gamma P_pi)^{-1} r_pi`` (the solve of :func:`policy_evaluation`)."""
    return discounted_chain_values(policy_matrix(model, pi), policy_rewards(model, pi, R), gamma)


def policy_evaluation(
    model: Model, pi: jax.Array, gamma: float | jax.Array = 0.99, rewards: jax.Array | None = None
) -> tuple[jax.Array, jax.Array]:
    """Exact discounted evaluation of a stationary policy: ``V = (I - gamma P_pi)^{-1} r_pi`` and its ``Q``.

    The solve is :func:`jaxmdp.jaxlib_workarounds.linalg.solve` (one system at a time under ``vmap``: jaxlib 0.10.2's
    batched CPU solve can deadlock)."""
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
    R = _rewards(model, rewards)
    vi = value_iteration(model, gamma, rewards=R, tol=vi_tol, max_iter=10_000)
    return policy_iteration(model, gamma, rewards=R, policy=greedy(vi.Q, _action_mask(model)))


# ---------------------------------------------------------------------------------------------------------------
# Finite horizon
# ---------------------------------------------------------------------------------------------------------------


def _horizon_args(model: Model, H: int | None, horizon: Any) -> tuple[int, jax.Array]:
    if H is None:
        if not isinstance(model, MDP) or model.H is None:
            raise ValueError("H must be given for a continuous MDP or a dense kernel")
        H = model.H
    if horizon is None:
        horizon = model.horizon if isinstance(model, MDP) and model.H is not None else H
    return H, jnp.asarray(horizon)


@compiled("H")
def finite_horizon_value_iteration(
    model: Model, rewards: jax.Array | None = None, H: int | None = None, horizon: Any = None
) -> tuple[jax.Array, jax.Array]:
    """Exact backward induction on a stationary model.

    Returns ``Q[H, S, A]`` and ``V[H + 1, S]`` with ``V[H] = 0``; time steps ``h >= horizon`` are worth zero.
    """
    R = _rewards(model, rewards)
    H, horizon = _horizon_args(model, H, horizon)

    def step(V_next, h):
        Q = jnp.where(h < horizon, q_values(model, V_next, 1.0, R), 0.0)
        V = jnp.max(Q, axis=-1)
        return V, (Q, V)

    V_H = jnp.zeros(R.shape[:1], R.dtype)
    _, (Q, V) = jax.lax.scan(step, V_H, jnp.arange(H), reverse=True)
    return Q, jnp.concatenate([V, V_H[None]], axis=0)


def _backward(step: Callable, V_H: jax.Array, xs: Any, all_steps: bool) -> Any:
    """Backward induction ``V_h = step(V_{h+1}, xs[h])`` from ``V_H``: ``(V[H + 1, S], ys)`` with ``ys`` the stacked
    extra outputs of ``step`` when ``all_steps``, else ``V_0`` alone. Without the stacked outputs the scan carries
    ``V`` only: the runner's indicators need ``V_0`` and nothing else, and writing every step's ``V`` (and ``Q``) cost
    a quarter of an episodic evaluation (Taxi, 512 members vmapped, one core: 11.4 -> 8.9 ms;
    docs/benchmarks/bench_agents_tabular.md)."""
    if all_steps:

        def keep(V_next, x):
            V, y = step(V_next, x)
            return V, (V, y)

        _, (V, ys) = jax.lax.scan(keep, V_H, xs, reverse=True)
        return jnp.concatenate([V, V_H[None]], axis=0), ys
    V_0, _ = jax.lax.scan(lambda V, x: (step(V, x)[0], None), V_H, xs, reverse=True)
    return V_0


def _policy_backup(model: Model, R: jax.Array, horizon: jax.Array) -> Callable:
    """One backward step of policy evaluation: ``(V_{h+1}, (h, pi_h)) -> (V_h, Q_h)``."""

    def step(V_next, x):
        h, pi_h = x
        Q = jnp.where(h < horizon, q_values(model, V_next, 1.0, R), 0.0)
        return jnp.sum(pi_h * Q, axis=-1), Q

    return step


def _time_indexed(pi: jax.Array, H: int, shape: tuple[int, ...]) -> jax.Array:
    return jnp.broadcast_to(pi, (H, *shape)) if pi.ndim == 2 else pi[:H]


@compiled("H")
def finite_horizon_policy_evaluation(
    model: Model, pi: jax.Array, rewards: jax.Array | None = None, H: int | None = None, horizon: Any = None
) -> tuple[jax.Array, jax.Array]:
    """Exact finite-horizon evaluation of ``pi[H, S, A]`` (time-indexed) or ``pi[S, A]`` (stationary).

    Returns ``Q[H, S, A]`` and ``V[H + 1, S]`` with ``V_h = sum_a pi_h(a|s) Q_h(s, a)``.
    """
    R = _rewards(model, rewards)
    H, horizon = _horizon_args(model, H, horizon)
    V_H = jnp.zeros(R.shape[:1], R.dtype)
    V, Q = _backward(_policy_backup(model, R, horizon), V_H, (jnp.arange(H), _time_indexed(pi, H, R.shape)), True)
    return Q, V


@compiled("H")
def finite_horizon_start_values(
    model: Model, pi: jax.Array, rewards: jax.Array | None = None, H: int | None = None, horizon: Any = None
) -> jax.Array:
    """``V_0[S]`` of :func:`finite_horizon_policy_evaluation` (the same numbers), without keeping the other steps'
    ``Q`` and ``V``: what an episodic regret indicator needs (``sum_s P0(s) V_0(s)``, paper App. A.1)."""
    R = _rewards(model, rewards)
    H, horizon = _horizon_args(model, H, horizon)
    V_H = jnp.zeros(R.shape[:1], R.dtype)
    return _backward(_policy_backup(model, R, horizon), V_H, (jnp.arange(H), _time_indexed(pi, H, R.shape)), False)


def successor_rows(mdp: MDP) -> jax.Array:
    """The successor lists packed one row per ``(s, a)``: ``[..., S, A, 2 K + 1]`` holding ``[p_1..p_K, R(s, a),
    succ_1..succ_K]``, the successor indices bit-cast to the reward dtype (exactly); of an MDP, or of a stacked one
    (a leading MDP axis). What :func:`finite_horizon_deterministic_evaluation` reads: one gather of the chosen rows
    per step instead of three (vmapped over 512 members on a CPU, one core: 5.4 -> 3.6 ms on MiniGridEmpty, 12.1 ->
    9.0 ms on Taxi, 1.7 -> 1.0 ms on RiverSwim; the same numbers)."""
    dtype = mdp.R.dtype
    succ = jax.lax.bitcast_convert_type(mdp.succ.astype(_same_width_int(dtype)), dtype)
    return jnp.concatenate([mdp.succ_p.astype(dtype), mdp.R[..., None], succ], axis=-1)


def _same_width_int(dtype: Any) -> Any:
    """The integer dtype that a float ``dtype`` bit-casts to (the successor columns of :func:`successor_rows`)."""
    return {4: jnp.int32, 8: jnp.int64}[jnp.dtype(dtype).itemsize]


def _deterministic_backup(mdp: MDP, rows: jax.Array | None, member: jax.Array | None) -> Callable:
    """One backward step of :func:`finite_horizon_deterministic_evaluation`: ``(V_{h+1}, (h, a_h)) -> (V_h, ())``,
    reading ``rows[member]`` (a stacked MDP's :func:`successor_rows`) when given, else the MDP's own."""
    _, horizon = _horizon_args(mdp, None, None)
    S, K = mdp.n_states, mdp.succ.shape[-1]
    states = jnp.arange(S)
    as_int = _same_width_int(mdp.R.dtype)
    table = successor_rows(mdp) if rows is None else rows
    index = (states,) if rows is None else (member, states)

    def step(V_next, x):
        h, a_h = x
        rows_h = table[(*index, a_h)]
        nxt = jax.lax.bitcast_convert_type(rows_h[:, K + 1:], as_int).reshape(-1)
        expected = jnp.sum(rows_h[:, :K] * jnp.take(V_next, nxt, mode="clip").reshape(S, K), axis=-1)
        return jnp.where(h < horizon, rows_h[:, K] + 1.0 * expected, 0.0), ()

    return step


@compiled()
def finite_horizon_deterministic_evaluation(mdp: MDP, actions: jax.Array) -> jax.Array:
    """``V[H + 1, S]`` of the deterministic time-indexed policy ``actions[H, S]`` (action indices) on an MDP's
    successor lists: ``V_h(s) = R(s, a_h(s)) + sum_k p_k V_{h+1}(s'_k)`` over the successors of ``(s, a_h(s))``,
    ``V_h = 0`` for ``h >= horizon``.

    The same numbers as :func:`finite_horizon_policy_evaluation` of the one-hot policy (``V_h = sum_a pi_h(a|s)
    Q_h(s, a)`` adds exact zeros to the chosen action's ``Q``), at ``O(H S K)`` instead of ``O(H S A K)``: only the
    chosen action's successor list is read.
    """
    V_H = jnp.zeros((mdp.n_states,), mdp.R.dtype)
    return _backward(_deterministic_backup(mdp, None, None), V_H, (jnp.arange(mdp.H), actions[: mdp.H]), True)[0]


@compiled()
def finite_horizon_deterministic_start_values(
    mdp: MDP, actions: jax.Array, rows: jax.Array | None = None, member: jax.Array | None = None
) -> jax.Array:
    """``V_0[S]`` of :func:`finite_horizon_deterministic_evaluation` (the same numbers), carrying ``V`` alone through
    the backward pass: the episodic indicators' evaluation of an agent's greedy actions (paper App. A.1).

    ``rows`` and ``member``: the :func:`successor_rows` of a stacked MDP and this MDP's index in the stack (``mdp``
    then supplies the horizon and sizes). Under ``vmap`` over the members of a stacked grid, every gather then reads
    the unbatched stack by ``(member, s, a)``; from each member's own packed table (a batched operand) XLA's CPU
    gather took about 10x as long (two Taxi MDPs, 512 members, one core: 155 against 14 ms a log,
    docs/benchmarks/bench_episodic_evaluation.md)."""
    if (rows is None) != (member is None):
        raise ValueError("rows and member go together: a stacked MDP's successor_rows and this MDP's index in it; "
                         f"got rows={'None' if rows is None else rows.shape} and member={member!r}")
    V_H = jnp.zeros((mdp.n_states,), mdp.R.dtype)
    backup = _deterministic_backup(mdp, rows, member)
    return _backward(backup, V_H, (jnp.arange(mdp.H), actions[: mdp.H]), False)


# ---------------------------------------------------------------------------------------------------------------
# Average reward
# ---------------------------------------------------------------------------------------------------------------


def _classes_from_reach(reach: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``(recurrent, same_class)`` of a reflexive-transitive reachability matrix: a state is recurrent when every
    state it reaches reaches it back."""
    recurrent = jnp.all(~reach | reach.T, axis=1)
    same_class = reach & reach.T & recurrent[:, None] & recurrent[None, :]
    return recurrent, same_class


@compiled()
def recurrent_classes(P: jax.Array, reach: jax.Array | None = None) -> tuple[jax.Array, jax.Array]:
    """Recurrent states of a stochastic matrix and its closed classes.

    Reachability comes from repeated squaring of the boolean adjacency (``O(S^3 log S)``, exact), unless ``reach``
    (``[S, S]`` bool, reflexive and transitive, e.g. from :func:`successor_reachability`) is given. A state is
    recurrent when every state it reaches reaches it back. Returns ``(recurrent[S], same_class[S, S])`` with
    ``same_class[s, t]`` true iff ``s`` and ``t`` are recurrent and in the same class.
    """
    if reach is None:
        S = P.shape[0]
        reach = ((P > 0) | jnp.eye(S, dtype=bool)).astype(P.dtype)
        n_squarings = max(1, (S - 1).bit_length())
        reach = jax.lax.fori_loop(0, n_squarings, lambda _, M: jnp.minimum(M @ M, 1.0), reach) > 0
    return _classes_from_reach(reach)


@compiled()
def successor_reachability(succ: jax.Array, edge: jax.Array) -> jax.Array:
    """``reach[s, t]``: whether ``t`` is reachable from ``s`` in zero or more steps along the successor slots
    ``s -> succ[s, ...]`` whose ``edge[s, ...]`` is true (e.g. ``pi(a|s) p(s, a, k) > 0``); ``[S, S]`` bool.

    Rows are bit sets (32 states a ``uint32`` word) and ``reach[s] |= reach[t]`` over the edges ``s -> t`` is swept
    until nothing changes: ``O(S^2 K / 32)`` word operations a sweep, and as many sweeps as the longest shortest path
    plus one (no dense ``S x S`` products; :func:`recurrent_classes` squares the dense adjacency instead).
    """
    S = succ.shape[0]
    states = jnp.arange(S)
    nbr = jnp.where(edge, succ, states.reshape((S,) + (1,) * (succ.ndim - 1))).reshape(S, -1)
    n_words = (S + 31) // 32
    word, bit = states // 32, (states % 32).astype(jnp.uint32)
    R = jnp.zeros((S, n_words), jnp.uint32).at[states, word].set(jnp.left_shift(jnp.uint32(1), bit))

    def body(c):
        R, _ = c
        R2 = R | jax.lax.reduce(R[nbr], jnp.uint32(0), jax.lax.bitwise_or, (1,))
        return R2, jnp.any(R2 != R)

    R = jax.lax.while_loop(lambda c: c[1], body, (R, jnp.asarray(True)))[0]
    return (jnp.right_shift(R[:, word], bit[None, :]) & jnp.uint32(1)) > 0


@compiled("block", "bandwidth")
def chain_gain(
    P: jax.Array,
    r: jax.Array,
    reach: jax.Array | None = None,
    block: int = GTH_BLOCK,
    order: jax.Array | None = None,
    bandwidth: int | None = None,
) -> jax.Array:
    """Long-run average reward ``g = P* r`` of a Markov chain from every state (``P*`` the Cesàro limit).

    Uses Grassmann-Taksar-Heyman elimination (:func:`jaxmdp.gth.gth_eliminate`, blocked: ``block`` states at a time,
    the trailing updates as matrix products), which only adds non-negative numbers and so stays accurate however
    slowly the chain mixes (a linear solve with ``I - P`` loses digits in proportion to the mixing time). States are
    ordered recurrent first and transient last; eliminating from the last position down, a recurrent state with no
    mass left towards lower positions is the root of its class. Back-substitution gives every class's stationary
    distribution (hence its gain; each class is renormalised on the fly to stay inside the floating-point range), and
    transient states average the gains they are absorbed into. ``O(S^3)`` plus the reachability of
    :func:`recurrent_classes` (or none, given ``reach``: ``P``'s reflexive-transitive reachability as there); handles
    periodic and multichain matrices. ``block = 1`` is the scalar elimination (larger blocks sum the same terms in
    another order).

    Banded (``order``, ``[S]``, a permutation of the states, and a static ``bandwidth``, e.g. from
    :func:`jaxmdp.gth.band_order`): the recurrent states come first and the transient ones last, each in ``order``'s
    order, and a transient state's mass into the recurrent states is one "absorbed" number (no recurrent state leads
    to a transient one). If then every transition joins positions at most ``bandwidth`` apart (checked, ``O(S^2)``),
    both parts are eliminated in one banded pass (:func:`jaxmdp.gth.gth_eliminate_banded`, ``O(S w^2)``), and a
    transient state's gain adds ``c_k``, the recurrent gains it moves to, carried down the elimination like its
    absorbed mass. Otherwise the dense elimination runs (a ``lax.cond``: use it per chain, not under ``vmap``).
    """
    if (order is None) != (bandwidth is None):
        raise ValueError("order and bandwidth go together: give both (jaxmdp.gth.band_order) or neither")
    S = P.shape[0]
    recurrent, same_class = recurrent_classes(P, reach)
    perm = _recurrent_first(jnp.arange(S) if order is None else order, recurrent)
    Pp, rec = P[perm][:, perm], recurrent[perm]
    args = (Pp, r[perm], rec, jnp.argmax(same_class, axis=1)[perm])
    if order is None:
        g = _gain_after_elimination(*args, block, None)
    else:
        fits = gth_bandwidth(jnp.where(~rec[:, None] & rec[None, :], 0.0, Pp)) <= bandwidth
        g = jax.lax.cond(
            fits, lambda: _gain_after_elimination(*args, BAND_BLOCK, bandwidth),
            lambda: _gain_after_elimination(*args, block, None),
        )
    return jnp.zeros((S,), P.dtype).at[perm].set(g)


def _recurrent_first(order: jax.Array, recurrent: jax.Array) -> jax.Array:
    """``order`` with its recurrent states first and its transient ones last, each in ``order``'s order."""
    return order[jnp.argsort(~recurrent[order], stable=True)]


def _window(x: jax.Array, k: jax.Array, width: int) -> tuple[jax.Array, jax.Array]:
    """The ``width`` entries of ``x`` (leading axis) from position ``max(k - width, 0)`` and a mask of those below
    ``k``: every position in ``[k - width, k)`` is among them."""
    start = jnp.maximum(k - width, 0)
    return jax.lax.dynamic_slice_in_dim(x, start, width), start + jnp.arange(width) < k


def _column_window(M: jax.Array, k: jax.Array, width: int) -> jax.Array:
    """Column ``k`` of ``M`` at the rows of :func:`_window`."""
    return jax.lax.dynamic_slice(M, (jnp.maximum(k - width, 0), k), (width, 1))[:, 0]


def _gain_after_elimination(
    P: jax.Array, r: jax.Array, rec: jax.Array, label: jax.Array, block: int, bandwidth: int | None,
    absorbed: tuple[jax.Array, Callable[[jax.Array], jax.Array]] | None = None,
) -> jax.Array:
    """:func:`chain_gain` of a chain whose recurrent states (``rec``) come first; ``label`` is the same for the states
    of a recurrent class. Banded (:func:`jaxmdp.gth.gth_eliminate_banded`) when ``bandwidth`` is given: then every
    transition other than from a transient to a recurrent state must join positions at most ``bandwidth`` apart.
    ``absorbed`` (banded only): ``P`` already without a transient state's moves into recurrent ones, given instead as
    their mass per state and a function of the recurrent gains ``g`` giving ``sum_j P[k, j] g_j`` over them (from
    successor lists: no ``S x S`` pass). A chain without transient states skips the transient part (two ``S``-step
    loops).

    Back-substitution reads only the ``w`` positions below each state (``w`` the bandwidth, else ``S``). The
    stationary masses can span more than float32's range within a class (ratios of 1e46 on a 50-state chain), so each
    is kept as a mantissa and a power-of-two exponent (``frexp``): a new mass sums its terms scaled by the largest
    term's power of two, and a class's masses are brought to its largest exponent before its gain is taken (scaling by
    a power of two is exact)."""
    S = P.shape[0]
    dtype = P.dtype
    W = S if bandwidth is None else min(max(bandwidth, 1), S)
    if bandwidth is None:
        M, scale = gth_eliminate(P, block)
    else:
        if absorbed is None:  # a transient state's moves into the recurrent ones: one absorbed mass
            into = ~rec[:, None] & rec[None, :]
            P_into, P = jnp.where(into, P, 0.0), jnp.where(into, 0.0, P)
            absorbed = jnp.sum(P_into, axis=1), lambda g: P_into @ g
        M, scale = gth_eliminate_banded(P, absorbed[0], bandwidth, block)
    root = rec & (scale == 0)
    lowest = jnp.iinfo(jnp.int32).min

    def stationary(k, me):
        mant, expo = me
        m, below = _window(mant, k, W)
        e, _ = _window(expo, k, W)
        col = _column_window(M, k, W)
        tm, te = jnp.frexp(m * col)  # each term mant * col = tm 2^te, times 2^e
        te = jnp.where(below & (tm > 0), te + e, lowest)
        top = jnp.max(te)
        val = jnp.sum(jnp.where(te > lowest, jnp.ldexp(tm, te - top), 0.0))
        vm, ve = jnp.frexp(val)
        vm = jnp.where(root[k], 0.5, jnp.where(rec[k], vm, 0.0))
        ve = jnp.where(root[k], 1, jnp.where(rec[k] & (val > 0), ve + top, 0))
        return mant.at[k].set(vm), expo.at[k].set(ve)

    mant, expo = jax.lax.fori_loop(0, S, stationary, (jnp.zeros((S,), dtype), jnp.zeros((S,), jnp.int32)))
    # Every class's masses on its largest exponent; class sums by label.
    mass = rec & (mant > 0)
    top = jax.ops.segment_max(jnp.where(mass, expo, lowest), label, num_segments=S)
    pi = jnp.where(mass, jnp.ldexp(mant, expo - top[label]), 0.0)
    num = jax.ops.segment_sum(pi * r, label, num_segments=S)
    den = jax.ops.segment_sum(pi, label, num_segments=S)
    g = jnp.where(rec, num[label] / jnp.where(rec, den[label], 1.0), 0.0)

    def transient(g: jax.Array) -> jax.Array:
        # c_k: the recurrent gains that transient k moves to, passed down like its absorbed mass (banded; densely,
        # the rows keep their recurrent columns).
        c_k = jnp.zeros((S,), dtype) if bandwidth is None else _pass_down(M, absorbed[1](g)[:, None], W)[:, 0]
        return _substitute_up(M, scale, c_k[:, None], g[:, None], rec, W)[:, 0]

    return jax.lax.cond(jnp.all(rec), lambda g: g, transient, g)


def _pass_down(M: jax.Array, c: jax.Array, width: int) -> jax.Array:
    """Columns ``c[S, m]`` carried down a (GTH) elimination whose stored columns ``col_k`` are in ``M`` (positions
    within ``width`` above the diagonal): ``c_i += col_k[i] c_k`` for ``i < k``, as ``k`` is eliminated, last position
    first. An absorbed mass, or a reward, passed on to the positions that remain."""
    S = M.shape[0]

    def step(t, c):
        k = S - 1 - t
        part, below = _window(c, k, width)
        col = jnp.where(below, _column_window(M, k, width), 0.0)
        return jax.lax.dynamic_update_slice_in_dim(c, part + col[:, None] * c[k][None, :], jnp.maximum(k - width, 0), 0)

    return jax.lax.fori_loop(0, S, step, c)


def _substitute_up(
    M: jax.Array, scale: jax.Array, c: jax.Array, x: jax.Array, fixed: jax.Array, width: int
) -> jax.Array:
    """Back-substitution after a (GTH) elimination, first position first: ``x_k = (sum_{j<k} M[k, j] x_j + c_k) /
    scale_k`` (the eliminated rows ``M[k, :k]``, within ``width`` below the diagonal; ``scale_k`` the mass leaving
    ``k`` downwards), for every ``k`` but the ``fixed`` ones, which keep ``x_k``. ``c``, ``x``: ``[S, m]``."""

    def step(k, x):
        part, below = _window(x, k, width)
        row = jnp.where(below, jax.lax.dynamic_slice(M, (k, jnp.maximum(k - width, 0)), (1, width))[0], 0.0)
        new = (jnp.sum(row[:, None] * part, axis=0) + c[k]) / jnp.where(scale[k] > 0, scale[k], 1.0)
        return x.at[k].set(jnp.where(fixed[k], x[k], new))

    return jax.lax.fori_loop(0, M.shape[0], step, x)


@compiled("n_squarings")
def chain_bias(P: jax.Array, r: jax.Array, n_squarings: int = 48) -> jax.Array:
    """Exact bias ``h = (I - P + P*)^{-1} (r - P* r)`` of a Markov chain ``P`` with rewards ``r``; ``P* h = 0``.

    ``P* = lim (I + P)^n / 2^n`` is the Cesàro limit (the lazy chain is aperiodic with the same limit), taken by
    ``n_squarings`` squarings (48: ``2^48`` steps, each renormalised to stay stochastic); the bias then solves
    Puterman 1994 Thm. A.7. Dense ``O(S^3)``; :func:`chain_gain` is the accurate route to the gain ``P* r`` alone.
    """
    eye = jnp.eye(P.shape[0], dtype=P.dtype)
    Pstar = cesaro_limit(P, n_squarings)
    g = Pstar @ r
    return linear_solve(eye - P + Pstar, r - g)


@compiled("n_squarings")
def cesaro_limit(P: jax.Array, n_squarings: int = 48) -> jax.Array:
    """``P* = lim_n (1/n) sum_{t<n} P^t``, taken as ``((I + P) / 2)^(2^n_squarings)`` (the lazy chain is aperiodic with
    the same limit; Puterman 1994 App. A.4), each square renormalised to stay stochastic. Dense ``O(S^3 n)``;
    periodic and multichain matrices alike."""
    eye = jnp.eye(P.shape[0], dtype=P.dtype)

    def square(_, M):
        M = M @ M
        return M / jnp.sum(M, axis=1, keepdims=True)

    return jax.lax.fori_loop(0, n_squarings, square, 0.5 * (eye + P))


def successor_policy_matrix(succ: jax.Array, succ_p: jax.Array, pi: jax.Array) -> jax.Array:
    """:func:`policy_matrix` of a model given by successor lists only: ``P_pi[s, s'] = sum_a pi(a|s) sum_k
    p[s,a,k] [succ[s,a,k] = s']`` (e.g. the continuous form of an episodic MDP, which has no dense kernel)."""
    S = succ.shape[0]
    w = (pi[:, :, None] * succ_p).reshape(S, -1)
    return jnp.zeros((S, S), succ_p.dtype).at[jnp.arange(S)[:, None], succ.reshape(S, -1)].add(w)


@compiled("bandwidth", "check_band")
def gain_vector(
    model: Model,
    pi: jax.Array,
    rewards: jax.Array | None = None,
    order: jax.Array | None = None,
    bandwidth: int | None = None,
    check_band: bool = True,
) -> jax.Array:
    """Long-run average reward of ``pi`` from every state: ``g = P*_pi r_pi`` (an ``[S]`` array; :func:`chain_gain`).

    An :class:`~jaxmdp.MDP`'s reachability comes from its successor lists (:func:`successor_reachability`: the same
    edges ``pi(a|s) P(s'|s,a) > 0`` as the dense ``P_pi``, without its ``O(S^3 log S)`` squarings). With the MDP's
    :func:`jaxmdp.gth.band_order` (``order``, and ``bandwidth`` static) the elimination is banded (``O(S w^2)``), the
    chain is written straight into that order from the successor lists, and a chain that is irreducible on the real
    states (two sweeps from one real state, forwards and backwards: every real state reaches it and is reached from
    it; padding states stay absorbing) skips the ``O(S^2)`` recurrent classes. The band is checked on the successor
    lists, and a chain outside it (a hand-made ``order``) is eliminated densely.

    ``check_band=False`` (static) compiles no dense branch, for an ``order`` that is the MDP's own
    :func:`jaxmdp.gth.band_order`, which every policy's chain fits: its recurrent states, then its transient ones,
    each in ``order``'s order, only come closer, and a transient state's moves into recurrent ones are the absorbed
    mass. A chain outside the band then gives NaN gains, not a wrong answer. The runner's programs compile 1-3 s
    faster (docs/benchmarks/bench_runner_compile.md, "unchecked band orders")."""
    if (order is None) != (bandwidth is None):
        raise ValueError("order and bandwidth go together: give both (jaxmdp.gth.band_order) or neither")
    r = policy_rewards(model, pi, rewards)
    if not isinstance(model, MDP):
        return chain_gain(policy_matrix(model, pi), r, order=order, bandwidth=bandwidth)
    S = model.n_states
    w = pi[:, :, None].astype(r.dtype) * model.succ_p
    edge = w > 0
    if order is None:
        return chain_gain(policy_matrix(model, pi), r, successor_reachability(model.succ, edge))
    states = jnp.arange(S)
    real = model.state_mask

    def classes():
        recurrent, same_class = _classes_from_reach(successor_reachability(model.succ, edge))
        return recurrent, jnp.argmax(same_class, axis=1)

    def one_class():  # the real states, and each padding state alone
        return jnp.ones((S,), bool), jnp.where(real, jnp.argmax(real), states)

    recurrent, label = jax.lax.cond(_irreducible(model.succ, edge, real), one_class, classes)
    perm = _recurrent_first(order, recurrent)
    pos = jnp.zeros((S,), jnp.int32).at[perm].set(states.astype(jnp.int32))
    src = jnp.broadcast_to(pos[:, None, None], w.shape)
    dst = pos[model.succ]
    rec = recurrent[perm]
    into = ~recurrent[:, None, None] & recurrent[model.succ]  # a transient state's slots into recurrent states
    # Every transition within the band, but for a transient state's moves into recurrent ones (its absorbed mass).
    inside = ~edge | into | (jnp.abs(src - dst) <= bandwidth)
    pi_p = pi[perm].astype(r.dtype)
    args = (r[perm], rec, label[perm])

    def banded() -> jax.Array:
        # Row i: state perm[i]; the moves into recurrent states as their mass and their gains, from the slots.
        P = successor_policy_matrix(dst[perm], jnp.where(into, 0.0, model.succ_p)[perm], pi_p)
        w_into = jnp.where(into, w, 0.0)
        absorbed = jnp.sum(w_into, axis=(1, 2))[perm], lambda g: jnp.sum(w_into * g[dst], axis=(1, 2))[perm]
        return _gain_after_elimination(P, *args, BAND_BLOCK, bandwidth, absorbed)

    def dense() -> jax.Array:
        return _gain_after_elimination(successor_policy_matrix(dst[perm], model.succ_p[perm], pi_p), *args,
                                       GTH_BLOCK, None)

    if not check_band:
        return jnp.where(jnp.all(inside), banded()[pos], jnp.nan)
    return jax.lax.cond(jnp.all(inside), banded, dense)[pos]


def _irreducible(succ: jax.Array, edge: jax.Array, real: jax.Array) -> jax.Array:
    """Whether the real states form one closed communicating class and every padding state is absorbing (the chain's
    classes are then the real states and each padding state alone): every real state reaches the first real state and
    is reached from it along the slots ``s -> succ[s, ...]`` whose ``edge`` holds (sweeps until nothing changes), no
    edge leaves the real states, and a padding state's edges lead to itself."""
    S = succ.shape[0]
    succ, edge = succ.reshape(S, -1), edge.reshape(S, -1)
    start = jnp.arange(S) == jnp.argmax(real)

    def sweep(step):
        def body(c):
            x, _ = c
            x2 = step(x)
            return x2, jnp.any(x2 != x)

        return jax.lax.while_loop(lambda c: c[1], body, (start, jnp.asarray(True)))[0]

    reaches = sweep(lambda x: x | jnp.any(edge & x[succ], axis=1))
    reached = sweep(lambda x: x.at[succ].max(edge & x[:, None]))
    closed = ~jnp.any(edge & real[:, None] & ~real[succ])
    closed &= ~jnp.any(edge & ~real[:, None] & (succ != jnp.arange(S)[:, None]))
    return closed & jnp.all(~real | (reaches & reached))


class GainBounds(struct.PyTreeNode):
    """Certified bounds ``lower <= g <= upper`` on the gain vector of a policy (:func:`successor_gain_bounds`),
    whether ``upper - lower`` met the tolerance everywhere, and the power sweeps used."""

    lower: jax.Array
    upper: jax.Array
    certified: jax.Array
    sweeps: jax.Array


def policy_successor_lists(mdp: MDP, pi: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The chain of ``pi`` on an MDP's successor lists: ``(succ[S, J], w[S, J], r[S])`` with ``w`` the probability of
    each successor slot under ``pi`` and ``r = r_pi``. A stochastic ``pi[S, A]`` keeps every action's slots
    (``J = A K``, ``w = pi(a|s) p[s, a, k]``); a deterministic policy given by its action indices (integer ``[S]``)
    keeps the chosen action's ``K`` slots only, an ``A``-fold smaller chain with the same kernel."""
    if jnp.issubdtype(pi.dtype, jnp.integer):
        s = jnp.arange(pi.shape[0])
        return mdp.succ[s, pi], mdp.succ_p[s, pi], mdp.R[s, pi]
    S = pi.shape[0]
    w = pi[:, :, None].astype(mdp.R.dtype) * mdp.succ_p
    return mdp.succ.reshape(S, -1), w.reshape(S, -1), jnp.sum(pi * mdp.R, axis=-1)


@compiled("inner_sweeps", "refine_sweeps", "give_up")
def successor_gain_bounds(
    mdp: MDP,
    pi: jax.Array,
    *,
    rtol: float = 1e-6,
    max_sweeps: int = 4096,
    inner_sweeps: int = 32,
    refine_sweeps: int | None = None,
    tau: float = 0.5,
    give_up: float | None = None,
) -> GainBounds:
    """Bounds on the gain vector ``g = P*_pi r_pi`` from sweeps over the successor lists (``O(S J)`` each, ``J = A K``
    for a stochastic ``pi[S, A]``, ``K`` for a deterministic one given by its integer action indices ``[S]``,
    :func:`policy_successor_lists`), no dense ``S x S`` work.

    With ``P_tau = tau P_pi + (1 - tau) I`` (aperiodic, same Cesàro limit ``P*``) and ``d_{n+1} = P_tau d_n``,
    ``d_0 = r_pi``: ``P* P_tau = P*`` gives ``P* d_n = g`` for every ``n``, and ``P*(s, .)`` puts mass only on states
    reachable from ``s``, so ``min_{t in Reach(s)} d_n(t) <= g(s) <= max_{t in Reach(s)} d_n(t)`` (Puterman 1994
    §8.2 for ``P*``). The reachable minimum and maximum are fixed points of ``m(s) <- min(m(s), min_{s -> t} m(t))``
    over the edges of positive probability. Since ``g = P_pi g``, a lower bound ``L`` improves to ``max(L, P_pi L)``
    (and an upper bound likewise), which tightens the bounds of transient states that reach several recurrent
    classes; each refresh applies it up to ``refine_sweeps`` times (default ``inner_sweeps``), stopping early once a
    pass changes neither bound (a fixed point: the remaining passes would change nothing, so the result is the same
    as that of all of them). Products with ``P_pi - I`` are summed as differences ``sum p (x(s') - x(s))``: kernel
    rows that sum to ``1 +- ulp`` would otherwise scale ``d`` a little at every sweep (1e-6 relative after a hundred
    float32 sweeps). Every ``inner_sweeps`` power sweeps the bounds are refreshed; the loop stops when
    ``upper - lower <= rtol (1 + |upper|)`` at every real state (``certified``) or after ``max_sweeps`` sweeps.
    Converges geometrically at the rate of the slowest class's mixing (and absorption, for transient states); a
    caller falls back to :func:`gain_vector` when not certified.

    ``give_up`` (static, e.g. 16): also stop, uncertified, after a refresh at whose rate of contraction (the widest
    gap in units of its tolerance, against the previous refresh's) the gap would need more than ``give_up`` times
    the refreshes left to certify. Where the bounds certify either way, the result is the same; on a slowly mixing
    chain a caller with an exact fallback saves the sweeps that would not have certified (docs/benchmarks/
    continuous_indicators.md, "Giving up early").
    """
    if give_up is not None and not give_up > 0:
        raise ValueError(f"give_up must be positive (a factor on the refreshes left) or None, got {give_up}")
    succ, w, r = policy_successor_lists(mdp, pi)
    dtype = w.dtype
    edge = w > 0
    inf = jnp.asarray(jnp.inf, dtype)
    real = mdp.state_mask
    S = r.shape[0]
    n_refine = inner_sweeps if refine_sweeps is None else refine_sweeps

    def drift(x):
        # (P_pi - I) x, summed as differences so that rows summing to 1 +- ulp add no error proportional to x itself
        return jnp.sum(w * (x[succ] - x[:, None]), axis=1)

    def reach_extreme(x, sign):
        # min (sign = 1) or max (sign = -1) of x over the states reachable from each state
        def body(c):
            m, _ = c
            m2 = jnp.minimum(m, jnp.min(jnp.where(edge, m[succ], inf), axis=1))
            return m2, jnp.any(m2 != m)

        return sign * jax.lax.while_loop(lambda c: c[1], body, (sign * x, jnp.asarray(True)))[0]

    def refine(c):
        lo, hi, i, _ = c
        lo2 = jnp.maximum(lo, lo + drift(jnp.where(jnp.isfinite(lo), lo, 0.0)))
        hi2 = jnp.minimum(hi, hi + drift(jnp.where(jnp.isfinite(hi), hi, 0.0)))
        return lo2, hi2, i + 1, jnp.any(lo2 != lo) | jnp.any(hi2 != hi)

    def refresh(lo, hi, d):
        lo = jnp.maximum(lo, reach_extreme(d, 1.0))
        hi = jnp.minimum(hi, reach_extreme(d, -1.0))
        init = (lo, hi, jnp.asarray(0, jnp.int32), jnp.asarray(True))
        lo, hi, _, _ = jax.lax.while_loop(lambda c: c[3] & (c[2] < n_refine), refine, init)
        tol = rtol * (1.0 + jnp.abs(hi))
        ok = jnp.all(~real | (hi - lo <= tol))
        gap = jnp.max(jnp.where(real, (hi - lo) / tol, 0.0))  # the widest gap in tolerances (<= 1 where certified)
        return lo, hi, ok, gap

    def cond(c):
        *_, ok, n, _, hopeless = c
        return ~ok & (n < max_sweeps) & ~hopeless

    def body(c):
        d, lo, hi, _, n, gap0, _ = c
        d = jax.lax.fori_loop(0, inner_sweeps, lambda _, d: d + tau * drift(d), d)
        lo, hi, ok, gap = refresh(lo, hi, d)
        n = n + inner_sweeps
        hopeless = jnp.zeros((), bool)
        if give_up is not None:
            # Refreshes still needed at the last one's rate of contraction, against those left.
            need = jnp.log(jnp.maximum(gap, 1.0)) / jnp.maximum(jnp.log(gap0) - jnp.log(gap), 0.0)
            hopeless = ~ok & (need > give_up * (max_sweeps - n) / inner_sweeps)
        return d, lo, hi, ok, n, gap, hopeless

    lo, hi, ok, gap = refresh(jnp.full((S,), -inf), jnp.full((S,), inf), r)
    init = (r, lo, hi, ok, jnp.asarray(0, jnp.int32), gap, jnp.zeros((), bool))
    _, lo, hi, ok, n, _, _ = jax.lax.while_loop(cond, body, init)
    return GainBounds(lower=lo, upper=hi, certified=ok, sweeps=n)


@compiled()
def policy_gain(
    model: Model, pi: jax.Array, start: jax.Array | None = None, rewards: jax.Array | None = None
) -> jax.Array:
    """Expected average reward ``rho = d^T P*_pi r_pi`` of a stationary policy from ``start`` (default ``P0``)."""
    if start is None:
        if not isinstance(model, MDP):
            raise ValueError("start must be given when the model is a dense kernel")
        start = model.P0
    return start @ gain_vector(model, pi, rewards)


class GainResult(struct.PyTreeNode):
    """Optimal average reward: ``gain`` of the returned greedy ``policy`` (exact, from the start distribution),
    the relative-value-iteration bounds ``lower <= rho* <= upper`` and its ``bias`` and ``Q``."""

    gain: jax.Array
    policy: jax.Array
    lower: jax.Array
    upper: jax.Array
    bias: jax.Array
    Q: jax.Array
    iterations: jax.Array
    converged: jax.Array


@compiled()
def optimal_gain(
    model: Model,
    *,
    rewards: jax.Array | None = None,
    start: jax.Array | None = None,
    tol: float = 1e-6,
    max_iter: int = 200_000,
    tau: float = 0.5,
) -> GainResult:
    """Gain-optimal policy of a weakly communicating MDP by relative value iteration (Puterman §8.5).

    Iterates ``h <- T h - (T h)(s_ref)`` on the aperiodic transform ``P_tau = tau P + (1 - tau) I`` (same stationary
    distributions, hence same gains and optimal policies). ``min_s (T h - h) <= rho* <= max_s (T h - h)``; it stops when
    the span of ``T h - h`` drops below ``tol * (1 + |rho|)``. The greedy policy's gain is then evaluated exactly with
    :func:`policy_gain`. For MDPs with several closed communicating classes the optimal gain depends on the start
    state, the bounds do not meet and ``converged`` is False.

    The same iteration as :func:`relative_value_iteration` (``h = u / tau``), with its own arithmetic: the direct
    backup of ``P_tau`` renormalised at state 0 keeps float32 round-off below the ``1e-6`` relative tolerance, where
    the incremental ``u + tau d`` of the planners (tolerance ``1e-3``) stalls above it on some benchmark MDPs (5 of
    66 tried) and breaks ties between optimal actions differently. Padded states (an MDP of a stacked batch) are left
    out of the stopping rule, as in :func:`relative_value_iteration`: their gain is 0, so with them the span would
    never fall below ``tol`` and a padded MDP would run all ``max_iter`` sweeps.
    """
    R = _rewards(model, rewards)
    mask = _action_mask(model)
    state_mask, _ = _masks(model, R)
    S = R.shape[0]
    if start is None:
        start = model.P0 if isinstance(model, MDP) else jnp.full((S,), 1.0 / S, R.dtype)

    inf = jnp.asarray(jnp.inf, R.dtype)

    def backup(h):
        return R + tau * expected_next_values(model, h) + (1.0 - tau) * h[:, None]

    def cond(c):
        _, lo, hi, i = c
        return ((i == 0) | (hi - lo > tol * (1.0 + jnp.abs(hi)))) & (i < max_iter)

    def body(c):
        h, _, _, i = c
        Th = jnp.max(backup(h), axis=-1)
        d = Th - h
        return Th - Th[0], jnp.min(jnp.where(state_mask, d, inf)), jnp.max(jnp.where(state_mask, d, -inf)), i + 1

    h, lo, hi, it = jax.lax.while_loop(cond, body, (jnp.zeros((S,), R.dtype), -inf, inf, jnp.asarray(0)))
    Q = backup(h)
    pi = greedy(Q, mask)
    rho = policy_gain(model, pi, start, R)
    converged = (hi - lo) <= tol * (1.0 + jnp.abs(hi))
    return GainResult(gain=rho, policy=pi, lower=lo, upper=hi, bias=h, Q=Q, iterations=it, converged=converged)
