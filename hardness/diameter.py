"""The diameter (paper §2.2, App. B; docs/measures.md §3): the worst-case expected time to travel between two states.

``D = max_{s1 != s2} min_pi E[T^pi(s1 -> s2)]``. For a target ``e`` the optimal hitting times solve the Bellman
equation of App. B, ``T*(s -> e) = min_a [1 + sum_{s' != e} P(s'|s,a) T*(s' -> e)]`` (``T*(e -> e) = 0``), and
``D = max_e max_s T*(s -> e)``.

``variant="paper"`` (default), continuous: all targets at once in an ``[S, E]`` layout (column ``e`` holds the hitting
times into ``e``), so each Jacobi backup gathers contiguous rows through the successor lists in ``O(S A K E)``. From
``V = 0`` the iterates are monotone lower bounds ``L_e = max_s V_e <= max_s T*(. -> e)``; with
``delta_e = max_s (T V_e - V_e) < 1`` the greedy policy satisfies ``(I - P_mu) V_e >= (1 - delta_e) 1`` and hence hits
``e`` within ``V_e / (1 - delta_e)`` steps on average (a rigorous upper bound ``U_e``). Once at most ``n_candidates``
targets can still hold the maximum (``U_e > max L``), the sweeps continue on those targets only. The result is
certified: ``max U <= (1 + rtol) max L``; the returned value is ``max L``. A graph that is not strongly connected
has an infinite diameter (returned as ``inf`` with ``converged=True``); running out of sweeps (e.g. ``p_lazy`` close
to 1, whose hitting times converge very slowly) returns ``inf`` with ``converged=False``.

``variant="paper"``, episodic: the continuous diameter of the time-augmented MDP, whose states are the reachable
pairs ``(h, s)`` (:func:`jaxmdp.episodic.reachable_pairs`; unreachable pairs are neither sources nor targets, so the
diameter is always finite). It has a closed form. Take a target pair ``(h_e, e)`` and let ``c`` be the optimal
expected hitting time from a fresh reset. From ``(h, s)`` with ``h > h_e`` the target cannot be hit before the next
reset, ``horizon - h`` steps away, so ``T* = horizon - h + c``. From ``h <= h_e`` a trip either hits at time ``h_e``
(taking ``h_e - h`` steps) or misses and takes ``horizon - h + c``; the expected time is affine in the hit
probability with a negative slope, so the optimal policy maximises the probability ``M_{h_e - h}[s, e]`` of being in
``e`` exactly ``h_e - h`` steps later, whatever ``c``:
``T* = horizon - h + c - (horizon - h_e + c) M_{h_e - h}[s, e]``. At the reset this gives
``c = horizon / q - (horizon - h_e)`` with ``q = P0 . M_{h_e}[:, e]``. The ``H`` matrices
``M_{k+1}[s, e] = max_a sum_s' P(s'|s,a) M_k[s', e]`` (``M_0 = I``, one all-targets backup each) serve every
target time, so the whole diameter costs two scans of ``H`` backups, ``O(H S A K S + H^2 S^2)``, with no iteration
and no ``(S H) x (S H)`` matrix.

``variant="colosseum"``: the reference's procedures, for parity with its numbers (docs/measures.md §3.1-3.2, both
[paper≠code] where they differ): continuous, per target value iteration with ``gamma = 1``, ``eps = 1e-3`` from 0
(Gauss-Seidel in index order, or Jacobi when the reference's size/sparsity rule applies), ``D = max(0, max_e d_e)``;
above 1000 states its sparse solver with the early exit on the running maximum (targets in index order). Episodic,
the reference's sweep on ``T_epi`` for each target *state* in the order ``S-1 .. 0`` with its two stopping rules
and the minimum over the in-episode times of the positive hitting times; a state that no in-episode time reaches
(on which the reference never stops) gives ``inf``. The reference's per-target early exits depend on the running
maximum of the targets before; all targets are swept in parallel, the value of each is recorded at the first sweep
under the loose and under the tight threshold, and the sequential exits are replayed afterwards (exact, because the
per-target values only grow with the sweeps). Both under-estimate the exact value slightly (stopping at ``eps``) and
the episodic one is a different quantity from the paper's.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from hardness.reference_vi import uses_jacobi
from hardness.result import MeasureResult
from jaxmdp._asserts import assert_mdp
from jaxmdp._checks import Variant, check_int, check_range, check_variant
from jaxmdp.dynamic_programming import compiled
from jaxmdp.episodic import reachable_pairs
from jaxmdp.mdp import MDP

__all__ = ["diameter", "strongly_connected"]


#: Above this many states the reference uses its sparse, early-exit hitting-time solver (single core).
SPARSE_DIAMETER_STATES = 1000


# ---------------------------------------------------------------------------------------------------------------
# Shared pieces
# ---------------------------------------------------------------------------------------------------------------


def _expect_columns(succ: jax.Array, succ_p: jax.Array, V: jax.Array) -> jax.Array:
    """``sum_k p[s, a, k] V[succ[s, a, k], :]`` for a column layout ``V[S, E]``: an ``[S, A, E]`` array.

    A loop over the (few) successor slots keeps each temporary at ``[S, A, E]`` and each gather row-contiguous.
    """
    acc = succ_p[:, :, 0, None] * V[succ[:, :, 0]]
    for k in range(1, succ.shape[-1]):
        acc = acc + succ_p[:, :, k, None] * V[succ[:, :, k]]
    return acc


def _hitting_backup(mdp: MDP, V: jax.Array, is_target: jax.Array, active: jax.Array) -> jax.Array:
    """One Jacobi backup of the hitting times ``V[S, E]``: ``1 + min_a P V`` off the targets, 0 on them and on
    inactive entries (padded states, finished or excluded targets)."""
    Q = 1.0 + _expect_columns(mdp.succ, mdp.succ_p, V)
    Q = jnp.where(mdp.action_mask[None, :, None], Q, jnp.inf)
    return jnp.where(is_target | ~active, 0.0, jnp.min(Q, axis=1))


@compiled()
def strongly_connected(mdp: MDP) -> jax.Array:
    """Whether every valid state can reach every other one (the MDP is communicating), by forward and backward
    reachability from state 0 through the successor lists (``O(S A K)`` per step, at most ``S`` steps). Jitted
    (:func:`jaxmdp.dynamic_programming.compiled`)."""
    S, _ = assert_mdp(mdp)
    edge = (mdp.succ_p > 0) & mdp.action_mask[None, :, None] & mdp.state_mask[:, None, None]
    start = jnp.arange(S) == 0

    def forward(r):
        hit = jnp.zeros((S,), jnp.int32).at[mdp.succ.ravel()].max((r[:, None, None] & edge).astype(jnp.int32).ravel())
        return r | (hit > 0)

    def backward(r):
        return r | jnp.any(edge & r[mdp.succ], axis=(1, 2))

    def closure(step):
        def cond(c):
            return c[1]

        def body(c):
            r, _ = c
            new = step(r)
            return new, jnp.any(new != r)

        return jax.lax.while_loop(cond, body, (start, jnp.asarray(True)))[0]

    valid = mdp.state_mask
    return jnp.all(closure(forward) | ~valid) & jnp.all(closure(backward) | ~valid)


# ---------------------------------------------------------------------------------------------------------------
# Paper, continuous
# ---------------------------------------------------------------------------------------------------------------


def _continuous_paper(mdp: MDP, rtol: float, max_iter: int, n_candidates: int) -> MeasureResult:
    S = mdp.n_states
    valid = mdp.state_mask
    connected = strongly_connected(mdp)
    idx = jnp.arange(S)
    dtype = mdp.dtype

    def bounds(V, V_new, cols_valid):
        # delta_e = max_s (T V - V)_e >= 0; U_e = max_s V_e / (1 - delta_e) when delta_e < 1.
        delta = jnp.max(jnp.where(valid[:, None], V_new - V, 0.0), axis=0)
        L = jnp.max(V_new, axis=0)
        U = jnp.where(delta < 1.0, jnp.max(V, axis=0) / jnp.maximum(1.0 - delta, 1e-30), jnp.inf)
        return jnp.where(cols_valid, L, -jnp.inf), jnp.where(cols_valid, jnp.maximum(U, L), -jnp.inf)

    # Phase 1: every target.
    is_target = idx[:, None] == idx[None, :]
    active = valid[:, None] & valid[None, :] & connected
    M = min(n_candidates, S)

    def done1(L, U):
        certified = jnp.max(U) <= (1.0 + rtol) * jnp.max(L)
        few = jnp.sum(U > jnp.max(L)) <= M
        return certified | few | ~connected

    def cond1(c):
        _, L, U, i = c
        return ~done1(L, U) & (i < max_iter)

    def body1(c):
        V, _, _, i = c
        V_new = _hitting_backup(mdp, V, is_target, active)
        L, U = bounds(V, V_new, valid)
        return V_new, L, U, i + 1

    inf = jnp.full((S,), jnp.inf, dtype)
    V0 = jnp.zeros((S, S), dtype)
    V, L, U, it1 = jax.lax.while_loop(cond1, body1, (V0, -inf, inf, jnp.asarray(0)))

    # Phase 2: the targets that may still hold the maximum.
    _, cand = jax.lax.top_k(U, M)
    is_target2 = idx[:, None] == cand[None, :]
    active2 = valid[:, None] & valid[cand][None, :] & connected
    chosen = jnp.zeros((S,), bool).at[cand].set(True)
    L_rest = jnp.max(jnp.where(chosen, -jnp.inf, L))
    U_rest = jnp.max(jnp.where(chosen, -jnp.inf, U))

    def cond2(c):
        _, L2, U2, i = c
        best = jnp.maximum(jnp.max(L2), L_rest)
        return (jnp.maximum(jnp.max(U2), U_rest) > (1.0 + rtol) * best) & (i < max_iter) & connected

    def body2(c):
        V2, _, _, i = c
        V_new = _hitting_backup(mdp, V2, is_target2, active2)
        L2, U2 = bounds(V2, V_new, valid[cand])
        return V_new, L2, U2, i + 1

    _, L2, U2, it2 = jax.lax.while_loop(cond2, body2, (V[:, cand], L[cand], U[cand], it1))
    best = jnp.maximum(jnp.max(L2), L_rest)
    certified = jnp.maximum(jnp.max(U2), U_rest) <= (1.0 + rtol) * best
    value = jnp.where(connected, best, jnp.inf)
    return MeasureResult.make(value, certified | ~connected)


# ---------------------------------------------------------------------------------------------------------------
# Paper, episodic (time-augmented MDP)
# ---------------------------------------------------------------------------------------------------------------


def _episodic_paper(mdp: MDP) -> MeasureResult:
    """Closed form on the time-augmented MDP (module docstring): ``M_k[s, e]``, the largest probability of being in
    ``e`` exactly ``k`` steps after ``s``, gives every hitting time of every target pair."""
    H, S = mdp.H, mdp.n_states
    dtype = mdp.dtype
    reach = reachable_pairs(mdp)  # [H, S]: sources and targets
    horizon = mdp.horizon.astype(dtype)
    he = jnp.arange(H, dtype=dtype)[:, None]  # target time, [H, 1]

    def next_M(M):
        Q = _expect_columns(mdp.succ, mdp.succ_p, M)
        Q = jnp.where(mdp.action_mask[None, :, None], Q, -jnp.inf)
        return jnp.where(mdp.state_mask[:, None], jnp.max(Q, axis=1), 0.0)

    eye = jnp.eye(S, dtype=dtype)
    # q[he, e] = P0 . M_he[:, e]: the best probability of a hit from a fresh reset.
    _, q = jax.lax.scan(lambda M, _: (next_M(M), mdp.P0 @ M), eye, None, length=H)
    c = jnp.where(q > 0, horizon / jnp.where(q > 0, q, 1.0) - (horizon - he), jnp.inf)  # [H, S]
    A = horizon - he + c
    # Sources after the target time: the next reset is (horizon - h) steps away, the worst is h = he + 1.
    best0 = jnp.where(he < horizon - 1, horizon - he - 1 + c, -jnp.inf)

    def sweep(carry, k):
        # Sources k steps before the target time: W = A + k - A * M_k[s, e], largest at the smallest M_k over the
        # states reachable at h = he - k.
        M, best = carry
        min_m = jnp.min(jnp.where(reach[:, :, None], M[None], jnp.inf), axis=1)  # [h, e]
        h = jnp.arange(H) - k
        mm = min_m[jnp.maximum(h, 0)]
        ok = (h >= 0)[:, None] & jnp.isfinite(mm)
        best = jnp.where(ok, jnp.maximum(best, A + k.astype(dtype) - A * mm), best)
        return (next_M(M), best), None

    (_, best), _ = jax.lax.scan(sweep, (eye, best0), jnp.arange(H))
    value = jnp.max(jnp.where(reach, best, -jnp.inf))
    # Every reachable target has a positive hit probability; only float underflow could make it 0.
    return MeasureResult.make(value, jnp.all(~reach | (q > 0)))


# ---------------------------------------------------------------------------------------------------------------
# Colosseum, continuous
# ---------------------------------------------------------------------------------------------------------------


def _continuous_colosseum(mdp: MDP, max_iter: int) -> MeasureResult:
    S = mdp.n_states
    valid = mdp.state_mask
    connected = strongly_connected(mdp)
    n_states = jnp.sum(valid)
    jacobi = uses_jacobi(mdp.succ_p, valid, mdp.action_mask)
    idx = jnp.arange(S)
    is_target = idx[:, None] == idx[None, :]
    cols = valid & connected
    eps = 1e-3
    dtype = mdp.dtype

    # Per-target value iteration with gamma = 1 on V = -ET; each target stops on its own (docs/measures.md §3.1).
    def gs_sweep(V, done):
        # A static trip count keeps the loop index unbatched under vmap (in-place row updates); padded rows and
        # Jacobi members keep their values.
        def body(s, V):
            q = -1.0 + jnp.sum(mdp.succ_p[s][:, :, None] * V[mdp.succ[s]], axis=1)  # [A, E]
            q = jnp.where(mdp.action_mask[:, None], q, -jnp.inf)
            keep = is_target[s] | done | jacobi | ~valid[s]
            return V.at[s].set(jnp.where(keep, V[s], jnp.max(q, axis=0)))

        return jax.lax.fori_loop(0, S, body, V)

    def jacobi_sweep(V, done):
        Q = -1.0 + _expect_columns(mdp.succ, mdp.succ_p, V)
        Q = jnp.where(mdp.action_mask[None, :, None], Q, -jnp.inf)
        return jnp.where(is_target | done[None, :] | ~valid[:, None], V, jnp.max(Q, axis=1))

    def cond(c):
        _, done, i = c
        return ~jnp.all(done) & (i < max_iter)

    def body(c):
        V, done, i = c
        # cond runs one branch for a single MDP; under vmap it becomes a select over both.
        V_new = jax.lax.cond(jacobi, jacobi_sweep, gs_sweep, V, done)
        diff = jnp.max(jnp.abs(V_new - V), axis=0)
        return V_new, done | (diff < eps), i + 1

    def dense():
        V, done, _ = jax.lax.while_loop(cond, body, (jnp.zeros((S, S), dtype), ~cols, jnp.asarray(0)))
        d = jnp.max(jnp.where(valid[:, None] & cols[None, :], -V, -jnp.inf), axis=0)
        value = jnp.where(connected, jnp.maximum(0.0, jnp.max(d)), jnp.inf)
        return MeasureResult.make(value, jnp.all(done) | ~connected)

    if S <= SPARSE_DIAMETER_STATES:
        return dense()
    # The path depends on the real number of states (a padded batch may mix both).
    return jax.lax.cond(
        n_states > SPARSE_DIAMETER_STATES, lambda: _continuous_colosseum_sparse(mdp, connected, max_iter), dense
    )


def _two_snapshot_scan(cur_a: jax.Array, cur_b: jax.Array, order: jax.Array, valid: jax.Array) -> jax.Array:
    """Replay the reference's sequential early exit: target ``e`` (in ``order``) stops with ``cur_a[e]`` (its value
    at the first sweep below the loose threshold) if ``cur_a[e] - 1`` is below the running maximum, else with
    ``cur_b[e]`` (its value at the tight threshold). Valid because the per-target values only grow with the sweeps.
    """

    def step(D, e):
        cur = jnp.where(cur_a[e] - 1.0 < D, cur_a[e], cur_b[e])
        return jnp.where(valid[e], jnp.maximum(D, cur), D), None

    D, _ = jax.lax.scan(step, jnp.asarray(-jnp.inf, cur_a.dtype), order)
    return D


def _continuous_colosseum_sparse(mdp: MDP, connected: jax.Array, max_iter: int) -> MeasureResult:
    """The reference's solver above 1000 states (docs/measures.md §3.1): Jacobi on the hitting times per target in index
    order, stopping at a change ``< 1e-3``, or ``< 0.05`` when ``max ET - 1`` is below the running maximum."""
    S = mdp.n_states
    valid = mdp.state_mask
    idx = jnp.arange(S)
    is_target = idx[:, None] == idx[None, :]
    active = valid[:, None] & valid[None, :] & connected

    def cond(c):
        _, _, _, done_b, i = c
        return ~jnp.all(done_b | ~(valid & connected)) & (i < max_iter)

    def body(c):
        V, cur_a, cur_b, done_b, i = c
        V_new = _hitting_backup(mdp, V, is_target, active)
        diff = jnp.max(jnp.abs(V_new - V), axis=0)
        cur = jnp.max(V_new, axis=0)
        first_a = (diff < 0.05) & ~jnp.isfinite(cur_a)
        first_b = (diff < 1e-3) & ~done_b
        cur_a = jnp.where(first_a, cur, cur_a)
        cur_b = jnp.where(first_b, cur, cur_b)
        return V_new, cur_a, cur_b, done_b | first_b, i + 1

    inf = jnp.full((S,), jnp.inf, mdp.dtype)
    init = (jnp.zeros((S, S), mdp.dtype), inf, inf, jnp.zeros((S,), bool), jnp.asarray(0))
    _, cur_a, cur_b, done_b, _ = jax.lax.while_loop(cond, body, init)
    D = _two_snapshot_scan(cur_a, cur_b, idx, valid)
    value = jnp.where(connected, jnp.maximum(0.0, D), jnp.inf)
    return MeasureResult.make(value, jnp.all(done_b | ~valid) | ~connected)


# ---------------------------------------------------------------------------------------------------------------
# Colosseum, episodic
# ---------------------------------------------------------------------------------------------------------------


def _episodic_colosseum(mdp: MDP, max_iter: int) -> MeasureResult:
    """docs/measures.md §3.2, all target states at once in a column layout ``ET[H][S, E]``, then the sequential early
    exit replayed with :func:`_two_snapshot_scan` over the targets ``S-1 .. 0``."""
    H, S = mdp.H, mdp.n_states
    reach = reachable_pairs(mdp)
    valid = mdp.state_mask
    idx = jnp.arange(S)
    is_target = idx[:, None] == idx[None, :]
    dtype = mdp.dtype

    def sweep(ET):
        reset = mdp.P0 @ (1.0 + ET[0])  # [E], from the previous sweep's h = 0 row

        def step(nxt, h):
            # Row h from row h + 1 (already updated in this sweep); arriving in e counts as a hit.
            body = 1.0 + _expect_columns(mdp.succ, mdp.succ_p, jnp.where(is_target, 0.0, nxt))
            body = jnp.min(jnp.where(mdp.action_mask[None, :, None], body, jnp.inf), axis=1)
            body = jnp.where(reach[h][:, None] & ~is_target, body, 0.0)
            row = jnp.where(h == mdp.horizon - 1, jnp.broadcast_to(reset, (S, S)), body)
            row = jnp.where(h < mdp.horizon, row, 0.0)
            return row, row

        _, rows = jax.lax.scan(step, jnp.zeros((S, S), dtype), jnp.arange(H), reverse=True)
        return rows

    def summary(ET):
        # m(s) = min of the positive entries of ET[:, s]; cur = max_s m(s), per target column.
        m = jnp.min(jnp.where(ET > 0, ET, jnp.inf), axis=0)
        return jnp.max(jnp.where(jnp.isfinite(m), m, -jnp.inf), axis=0)

    def cond(c):
        _, _, _, done_b, i = c
        return ~jnp.all(done_b | ~valid) & (i < max_iter)

    def body(c):
        ET, cur_a, cur_b, done_b, i = c
        ET_new = sweep(ET)
        diff = jnp.max(jnp.abs(ET_new - ET), axis=(0, 1))
        cur = summary(ET_new)
        first_a = (diff < 0.01) & ~jnp.isfinite(cur_a)
        first_b = (diff < 1e-3) & ~done_b
        cur_a = jnp.where(first_a, cur, cur_a)
        cur_b = jnp.where(first_b, cur, cur_b)
        return ET_new, cur_a, cur_b, done_b | first_b, i + 1

    # A state that no in-episode time reaches is never hit: the reference's sweep diverges on it (it never stops);
    # its hitting time is infinite, so is the result.
    never = valid & ~jnp.any(reach, axis=0)
    inf = jnp.full((S,), jnp.inf, dtype)
    init = (jnp.zeros((H, S, S), dtype), inf, inf, never, jnp.asarray(0))
    _, cur_a, cur_b, done_b, _ = jax.lax.while_loop(cond, body, init)
    D = _two_snapshot_scan(cur_a, cur_b, idx[::-1], valid & ~never)
    D = jnp.where(jnp.any(never), jnp.inf, D)
    return MeasureResult.make(D, jnp.all(done_b | ~valid))


# ---------------------------------------------------------------------------------------------------------------
# Public entry point
# ---------------------------------------------------------------------------------------------------------------


@functools.partial(jax.jit, static_argnames=("variant", "rtol", "max_iter", "n_candidates"))
def _diameter(mdp: MDP, variant: str, rtol: float, max_iter: int, n_candidates: int) -> MeasureResult:
    assert_mdp(mdp)
    if variant == "paper":
        if mdp.episodic:
            return _episodic_paper(mdp)
        return _continuous_paper(mdp, rtol, max_iter, n_candidates)
    if mdp.episodic:
        return _episodic_colosseum(mdp, max_iter)
    return _continuous_colosseum(mdp, max_iter)


def diameter(
    mdp: MDP,
    *,
    variant: Variant = "paper",
    rtol: float = 1e-6,
    max_iter: int = 100_000,
    n_candidates: int = 8,
) -> MeasureResult:
    """The diameter of ``mdp`` (module docstring), as a :class:`~hardness.MeasureResult`.

    Args:
      mdp: a single MDP; ``jax.vmap`` over a stacked batch of equal shapes for many (MDPs of different sizes:
        :func:`hardness.measures_many`, which maps over size buckets; module docstring of :mod:`hardness.batched`).
      variant: ``"paper"`` (exact, certified to ``rtol``) or ``"colosseum"`` (the reference's procedure).
      rtol: relative certificate of the continuous paper variant, ``max U <= (1 + rtol) max L``. Float32 round-off
        bounds what is reachable: values are exact to about ``1e-6`` relative; a tolerance far below the dtype's
        precision may leave ``converged=False``. (The episodic paper variant is a closed form.)
      max_iter: sweep budget of the iterative variants; exhausting it returns ``inf`` with ``converged=False``.
      n_candidates: continuous paper variant: how many targets the second phase keeps.
    """
    check_variant(variant)
    check_range("rtol", rtol, 0.0, 1.0, low_open=True, high_open=True)
    max_iter = check_int("max_iter", max_iter)
    n_candidates = check_int("n_candidates", n_candidates)
    return _diameter(mdp.strip(), variant, float(rtol), int(max_iter), int(n_candidates))
