"""Average reward (paper §2.1): the gains of stationary policies on a model, certified gain bounds, and the optimal
gain.

The gain of a policy from a start distribution ``d`` is ``rho = d^T P*_pi r_pi`` with ``P*_pi`` the Cesàro limit of
the policy's chain. This is the paper's ``<mu^pi, R^pi>`` when the chain has one recurrent class, and its natural
extension (the expected long-run average reward from ``d``) otherwise. Exact gains come from GTH elimination
(:mod:`jaxmdp.dynamic_programming.markov_chains`, :mod:`jaxmdp.gth`), banded on an MDP's
:func:`jaxmdp.gth.band_order`; :func:`successor_gain_bounds` bounds them with sweeps over the successor lists alone.
"""

from __future__ import annotations

import chex
import jax
import jax.numpy as jnp

from jaxmdp import struct
from jaxmdp._asserts import assert_mdp, assert_model, assert_policy

from jaxmdp.dynamic_programming.backups import (
    Model,
    _action_mask,
    _masks,
    _rewards,
    compiled,
    expected_next_values,
    greedy,
    policy_matrix,
    policy_rewards,
)
from jaxmdp.dynamic_programming.markov_chains import (
    _classes_from_reach,
    _gain_after_elimination,
    _recurrent_first,
    chain_gain,
    successor_reachability,
)
from jaxmdp.gth import BAND_BLOCK, GTH_BLOCK
from jaxmdp.mdp import MDP

__all__ = [
    "successor_policy_matrix",
    "gain_vector",
    "GainBounds",
    "policy_successor_lists",
    "successor_gain_bounds",
    "policy_gain",
    "GainResult",
    "optimal_gain",
]


def successor_policy_matrix(succ: jax.Array, succ_p: jax.Array, pi: jax.Array) -> jax.Array:
    """:func:`~jaxmdp.dynamic_programming.policy_matrix` of a model given by successor lists only: ``P_pi[s, s'] =
    sum_a pi(a|s) sum_k p[s,a,k] [succ[s,a,k] = s']`` (e.g. the continuous form of an episodic MDP, which has no dense
    kernel)."""
    chex.assert_rank(succ, 3, custom_message="succ: successor lists [S, A, K]")
    chex.assert_equal_shape([succ, succ_p], custom_message="succ and succ_p: successor lists [S, A, K]")
    chex.assert_shape(pi, succ.shape[:2], custom_message="pi: a policy [S, A]")
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
    """Long-run average reward of ``pi`` from every state: ``g = P*_pi r_pi`` (an ``[S]`` array;
    :func:`~jaxmdp.dynamic_programming.chain_gain`).

    An :class:`~jaxmdp.MDP`'s reachability comes from its successor lists
    (:func:`~jaxmdp.dynamic_programming.successor_reachability`: the same edges ``pi(a|s) P(s'|s,a) > 0`` as the dense
    ``P_pi``, without its ``O(S^3 log S)`` squarings). With the MDP's :func:`jaxmdp.gth.band_order` (``order``, and
    ``bandwidth`` static) the elimination is banded (``O(S w^2)``), the chain is written straight into that order from
    the successor lists, and a chain that is irreducible on the real states (two sweeps from one real state, forwards
    and backwards: every real state reaches it and is reached from it; padding states stay absorbing) skips the
    ``O(S^2)`` recurrent classes. The band is checked on the successor lists, and a chain outside it (a hand-made
    ``order``) is eliminated densely.

    ``check_band=False`` (static) compiles no dense branch, for an ``order`` that is the MDP's own
    :func:`jaxmdp.gth.band_order`, which every policy's chain fits: its recurrent states, then its transient ones,
    each in ``order``'s order, only come closer, and a transient state's moves into recurrent ones are the absorbed
    mass. A chain outside the band then gives NaN gains, not a wrong answer. The runner passes it because the dense
    branch it leaves out is a large part of its programs' compile time (docs/performance.md, Compilation)."""
    if (order is None) != (bandwidth is None):
        raise ValueError("order and bandwidth go together: give both (jaxmdp.gth.band_order) or neither")
    S, A = assert_model(model, rewards)
    assert_policy(pi, S, A)
    if order is not None:
        chex.assert_shape(order, (S,), custom_message="order: a permutation of the states [S]")
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
    S, A = assert_mdp(mdp)
    if jnp.issubdtype(pi.dtype, jnp.integer):
        chex.assert_shape(pi, (S,), custom_message="pi: action indices [S] (or a policy [S, A])")
        s = jnp.arange(pi.shape[0])
        return mdp.succ[s, pi], mdp.succ_p[s, pi], mdp.R[s, pi]
    assert_policy(pi, S, A)
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
    chain a caller with an exact fallback saves the sweeps that would not have certified (docs/performance.md,
    Continuous indicators).
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
    chex.assert_shape(start, (assert_model(model)[0],), custom_message="start: a distribution [S]")
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
    patience: int = 1_000,
) -> GainResult:
    """Gain-optimal policy of a weakly communicating MDP by relative value iteration (Puterman §8.5).

    Iterates ``h <- T h - (T h)(s_ref)`` on the aperiodic transform ``P_tau = tau P + (1 - tau) I`` (same stationary
    distributions, hence same gains and optimal policies). ``min_s (T h - h) <= rho* <= max_s (T h - h)``; it stops when
    the span of ``T h - h`` drops below ``tol * (1 + |rho|)``. The greedy policy's gain is then evaluated exactly with
    :func:`policy_gain`. For MDPs with several closed communicating classes the optimal gain depends on the start
    state, the bounds do not meet and ``converged`` is False.

    The same iteration as :func:`~jaxmdp.dynamic_programming.relative_value_iteration` (``h = u / tau``), with its
    own arithmetic: the direct backup of ``P_tau`` renormalised at state 0 keeps float32 round-off below the ``1e-6``
    relative tolerance, where the incremental ``u + tau d`` of the planners (tolerance ``1e-3``) stalls above it on
    some benchmark MDPs and breaks ties between optimal actions differently. Padded states (an MDP of a stacked batch)
    are left out of the stopping rule, as in :func:`~jaxmdp.dynamic_programming.relative_value_iteration`: their gain
    is 0, so with them the span would never fall below ``tol`` and a padded MDP would run all ``max_iter`` sweeps.

    It also stops after ``patience`` sweeps without a smaller span. In exact arithmetic the span of ``T h - h`` never
    grows (``sp(T u - T v) <= sp(u - v)``, Puterman §8.5.2), so a span that has not shrunk in that many sweeps has met
    the round-off floor of the values (a few units in the last place of ``|h|``, which exceeds ``tol`` when the bias is
    large: the 784- and 948-state MiniGrids of the benchmark stall at a span of ``3.8e-6`` within 500 sweeps) or the
    several gains of a multichain MDP; sweeping on to ``max_iter`` would change nothing (docs/performance.md,
    Indicator constants). ``converged`` still reports whether the span met ``tol``.
    """
    S, _ = assert_model(model, rewards)
    if start is not None:
        chex.assert_shape(start, (S,), custom_message="start: a distribution [S]")
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
        _, lo, hi, i, _, since = c
        return ((i == 0) | (hi - lo > tol * (1.0 + jnp.abs(hi)))) & (i < max_iter) & (since < patience)

    def body(c):
        h, _, _, i, best, since = c
        Th = jnp.max(backup(h), axis=-1)
        d = Th - h
        lo, hi = jnp.min(jnp.where(state_mask, d, inf)), jnp.max(jnp.where(state_mask, d, -inf))
        shrunk = hi - lo < best
        return Th - Th[0], lo, hi, i + 1, jnp.where(shrunk, hi - lo, best), jnp.where(shrunk, 0, since + 1)

    init = (jnp.zeros((S,), R.dtype), -inf, inf, jnp.asarray(0), inf, jnp.asarray(0))
    h, lo, hi, it, _, _ = jax.lax.while_loop(cond, body, init)
    Q = backup(h)
    pi = greedy(Q, mask)
    rho = policy_gain(model, pi, start, R)
    converged = (hi - lo) <= tol * (1.0 + jnp.abs(hi))
    return GainResult(gain=rho, policy=pi, lower=lo, upper=hi, bias=h, Q=Q, iterations=it, converged=converged)
