"""Extended value iteration over box confidence sets (Jaksch et al. 2010 §3.1; Fruit et al. 2020, UCRL2B).

The plausible kernels of a pair ``(s, a)`` are the distributions ``p`` on the real states with
``lo(s') <= p(s') <= hi(s')`` for every ``s'`` (a per-next-state, Bernstein-type box), where
``lo = max(0, p_hat - beta)`` and ``hi = min(1, p_hat + beta)``. The optimistic inner problem

    max_p  sum_s' p(s') u(s')   s.t.  lo <= p <= hi,  sum_s' p(s') = 1

is a linear programme whose optimum is greedy: start from ``lo`` and hand the missing mass ``1 - sum lo`` to the
next states in decreasing order of ``u``, each up to its ``hi`` (an exchange argument: moving mass from a lower- to
a higher-valued state never decreases the objective). One ordering of the states serves every pair of a sweep.

Extended value iteration runs :func:`jaxmdp.dynamic_programming.relative_value_iteration` with this backup and the span
stopping rule, which yields an optimistic gain within ``tol`` of the best gain over all plausible MDPs and a policy
that attains it in the optimistic kernel.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmdp.dynamic_programming import PlanResult, relative_value_iteration

__all__ = [
    "confidence_box",
    "optimistic_expectation",
    "optimistic_kernel",
    "extended_value_iteration",
    "sparse_optimistic_expectation",
    "sparse_extended_value_iteration",
    "colosseum_optimistic_kernel",
    "colosseum_extended_value_iteration",
]


def confidence_box(p_hat: jax.Array, width: jax.Array, state_mask: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Bounds ``lo = max(0, p_hat - width)``, ``hi = min(1, p_hat + width)`` on real next states, 0 on padded ones."""
    lo = jnp.where(state_mask, jnp.maximum(p_hat - width, 0.0), 0.0)
    hi = jnp.where(state_mask, jnp.minimum(p_hat + width, 1.0), 0.0)
    return lo, hi


_BLOCK = 32  # block length of the running sums in _exclusive_running_sum
#: From this many states on, EVI sorts (``O(S)`` per row and sweep) instead of the dense ``room @ precedes`` product
#: (``O(S^2)``), which is faster for small ``S`` on the CPU; the crossover lies between the benchmark's 108 and 400
#: states (docs/performance.md, Continuous planning).
SORTED_FROM = 200


def _exclusive_running_sum(x: jax.Array) -> jax.Array:
    """``y[i] = sum_{j < i} x[j]`` along the first axis of ``x[S, R]``, in blocks of :data:`_BLOCK`: a strictly
    triangular product within each block plus the running total of the blocks before it (two small products,
    ``O(S (B + S / B))`` per column, where ``jnp.cumsum`` on the CPU was several times slower)."""
    S = x.shape[0]
    n_blocks = -(-S // _BLOCK)
    xb = jnp.pad(x, [(0, n_blocks * _BLOCK - S), (0, 0)]).reshape(n_blocks, _BLOCK, -1)
    strictly_before = lambda n: jnp.tril(jnp.ones((n, n), x.dtype), k=-1)  # noqa: E731  [s, t] = [t < s]
    within = jnp.einsum("st,btr->bsr", strictly_before(_BLOCK), xb)
    blocks = strictly_before(n_blocks) @ jnp.sum(xb, axis=1)
    return (within + blocks[:, None]).reshape(n_blocks * _BLOCK, -1)[:S]


def _sorted_extra_mass(room_t: jax.Array, budget: jax.Array, order: jax.Array) -> jax.Array:
    """:func:`_extra_mass` in the next states' order ``order`` (decreasing ``u``) and transposed: ``room_t[S, R]``
    (``room = hi - lo`` of ``R`` rows, next state first), ``budget[R] = 1 - sum lo``; returns ``[S, R]`` whose row
    ``i`` is the mass added to next state ``order[i]``."""
    room = room_t[order]
    return jnp.clip(budget - _exclusive_running_sum(room), 0.0, room)


def _dense_extra_mass(lo: jax.Array, hi: jax.Array, u: jax.Array) -> jax.Array:
    """:func:`_extra_mass` by the dense product ``room @ precedes``, ``precedes[t, s] = [t comes before s]``."""
    S = u.shape[-1]
    idx = jnp.arange(S)
    precedes = (u[:, None] > u[None, :]) | ((u[:, None] == u[None, :]) & (idx[:, None] < idx[None, :]))
    room = hi - lo
    before = room @ precedes.astype(lo.dtype)
    budget = 1.0 - jnp.sum(lo, axis=-1, keepdims=True)
    return jnp.clip(budget - before, 0.0, room)


def _extra_mass(lo: jax.Array, hi: jax.Array, u: jax.Array) -> jax.Array:
    """Mass added on top of ``lo``: states in decreasing order of ``u`` (ties: lower index first) fill their box up
    to ``hi`` until the budget ``1 - sum lo`` is spent.

    The mass ahead of each state is an exclusive running sum of ``room = hi - lo`` in that order: one sort of ``u``
    (shared by every row), a gather of whole next-state rows of the transposed ``room`` and the running sum
    (:func:`_exclusive_running_sum`). (The dense ``room @ precedes`` product with ``precedes[t, s] = [t comes before
    s]``, ``O(S^2)`` per row, is kept below :data:`SORTED_FROM` states, where it is faster (docs/performance.md,
    Continuous planning); the two differ by rounding in the last bits.)
    """
    S = u.shape[-1]
    if S < SORTED_FROM:
        return _dense_extra_mass(lo, hi, u)
    _, room_t, budget = _transposed_boxes(lo, hi)
    order = jnp.argsort(-u, stable=True)
    extra = _sorted_extra_mass(room_t, budget, order)
    return extra[jnp.argsort(order)].T.reshape(lo.shape)


def _transposed_boxes(lo: jax.Array, hi: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """``(lo_t[S, R], room_t[S, R], budget[R])``: the boxes' ``R`` rows next state first, ``room = hi - lo``, and
    the mass ``1 - sum lo`` each row has left to place (the sorted path's sweep-invariant inputs)."""
    S = lo.shape[-1]
    lo_t, room_t = lo.reshape(-1, S).T, (hi - lo).reshape(-1, S).T
    return lo_t, room_t, 1.0 - jnp.sum(lo_t, axis=0)


def optimistic_expectation(lo: jax.Array, hi: jax.Array, u: jax.Array) -> jax.Array:
    """``max_p sum_s' p(s') u(s')`` over ``{lo <= p <= hi, sum p = 1}`` for every row of ``lo``/``hi`` ``[..., S]``.

    Requires ``sum lo <= 1 <= sum hi`` per row (true for boxes around a distribution).
    """
    return jnp.sum((lo + _extra_mass(lo, hi, u)) * u, axis=-1)


def optimistic_kernel(lo: jax.Array, hi: jax.Array, u: jax.Array) -> jax.Array:
    """The maximiser ``p~`` of :func:`optimistic_expectation` (``[..., S]``)."""
    return lo + _extra_mass(lo, hi, u)


@jax.jit  # an eager call compiles its loop once per shape, not at every call
def extended_value_iteration(
    p_hat: jax.Array,
    width: jax.Array,
    rewards: jax.Array,
    state_mask: jax.Array,
    action_mask: jax.Array,
    *,
    u0: jax.Array | None = None,
    tol: float | jax.Array = 1e-3,
    max_iter: int = 100_000,
    aperiodicity: float | jax.Array = 0.5,
    active: bool | jax.Array = True,
) -> PlanResult:
    """Optimistic average-reward planning: ``u <- max_a [r~(s,a) + max_{p in box(s,a)} p . u]`` to ``span < tol``.

    Args:
      p_hat: ``[S, A, S]`` estimated kernel (any row for unvisited pairs; give them ``width >= 1``).
      width: ``[S, A, S]`` (or broadcastable) half-widths of the per-next-state confidence intervals.
      rewards: ``[S, A]`` optimistic rewards ``r~``.
      u0: warm start (default 0); the stopping rule, not the start, certifies the result.
      active: False skips the iterations (see :func:`~jaxmdp.dynamic_programming.relative_value_iteration`).

    Returns a :class:`~jaxmdp.dynamic_programming.PlanResult` whose ``Q(s, a) = r~(s, a) + max_p p . u`` is the
    optimistic action value (relative to ``u``) and whose gain bounds bracket the optimistic gain.
    """
    lo, hi = confidence_box(p_hat, width, state_mask)
    u0 = jnp.zeros(rewards.shape[:1], rewards.dtype) if u0 is None else u0
    # optimistic_expectation with the sweep-invariant parts hoisted: the boxes transposed (next state first) once.
    sorted_path = u0.shape[0] >= SORTED_FROM
    if sorted_path:
        lo_t, room_t, budget = _transposed_boxes(lo, hi)

    def backup(u):
        if not sorted_path:
            return rewards + optimistic_expectation(lo, hi, u)
        order = jnp.argsort(-u, stable=True)
        value = u @ lo_t + u[order] @ _sorted_extra_mass(room_t, budget, order)
        return rewards + value.reshape(rewards.shape)

    return relative_value_iteration(
        backup,
        u0,
        state_mask,
        action_mask,
        discount=1.0,
        tol=tol,
        max_iter=max_iter,
        aperiodicity=aperiodicity,
        active=active,
    )


# ---------------------------------------------------------------------------------------------------------------
# Boxes given on each pair's observed next states (UCRL2's plan)
# ---------------------------------------------------------------------------------------------------------------
#
# A pair's box is ``[lo_k, hi_k]`` at its ``K`` slot states (the observed next states; an empty slot is a box
# ``[0, c]``) and ``[0, c]`` at every other real state, ``c`` the pair's width at ``p_hat = 0``. With the real states
# in decreasing order of ``u`` (ties: lower index first), the mass placed before position ``i`` is
# ``M(i) = c i + sum_{k: rank_k < i} (room_k - c)`` (``room = hi - lo``), non-decreasing in ``i``. The greedy fill of
# the module docstring fills every position before the first ``m`` with ``M(m + 1) >= B`` (``B = 1 - sum lo``), gives
# position ``m`` the rest ``B - M(m)``, and nothing after. So
#
#     max_p p . u = sum_k lo_k u_k + c U(m) + sum_{k: rank_k < m} (room_k - c) u_k + (B - M(m)) u_(m),
#
# with ``U(m)`` the sum of the ``m`` largest values of ``u`` (one running sum per sweep, shared by every pair) and
# ``m`` found by bisection on ``M`` (``O(K log S)`` per pair): ``O(S log S + S A K log S)`` per sweep instead of
# ``O(S A S)``.


def _bisection_steps(n: int) -> int:
    """Halvings that narrow ``[0, n - 1]`` to one position."""
    return max(1, int(n - 1).bit_length())


def sparse_optimistic_expectation(
    u: jax.Array, states: jax.Array, lo: jax.Array, hi: jax.Array, room_other: jax.Array, state_mask: jax.Array
) -> jax.Array:
    """``max_p sum_s' p(s') u(s')`` over each pair's box (the section comment above), ``[S, A]``.

    Args:
      u: ``[S]`` values of the next states.
      states: ``[S, A, K]`` slot states (distinct real states per pair, or empty slots with ``lo = 0, hi = c``).
      lo, hi: ``[S, A, K]`` bounds at the slots.
      room_other: ``[S, A]`` upper bound ``c`` at every real state outside the slots (lower bound 0).
      state_mask: ``[S]`` real states.
    Requires ``sum lo <= 1 <= sum hi`` per pair, as :func:`optimistic_expectation`.
    """
    S = u.shape[0]
    dtype = u.dtype
    order = jnp.argsort(jnp.where(state_mask, -u, jnp.inf), stable=True)
    rank = jnp.zeros((S,), jnp.int32).at[order].set(jnp.arange(S, dtype=jnp.int32))
    u_sorted = jnp.where(state_mask[order], u[order], 0.0)
    # U(m) for m = 0 .. S - 1 (m never reaches S: it is a position): blocked running sums, rounding error
    # ~ (32 + S / 32) ulp rather than S ulp.
    U = _exclusive_running_sum(u_sorted[:, None])[:, 0]
    n_real = jnp.sum(state_mask).astype(jnp.int32)
    r = rank[states]
    c = room_other[..., None]
    delta = (hi - lo) - c
    budget = 1.0 - jnp.sum(lo, axis=-1)

    def mass_through(i):  # M(i + 1): mass of positions 0 .. i
        return room_other * (i + 1).astype(dtype) + jnp.sum(jnp.where(r <= i[..., None], delta, 0.0), axis=-1)

    def halve(_, bounds):
        low, high = bounds
        mid = (low + high) // 2
        enough = mass_through(mid) >= budget
        return jnp.where(enough, low, mid + 1), jnp.where(enough, mid, high)

    low = jnp.zeros(room_other.shape, jnp.int32)
    high = jnp.broadcast_to(n_real - 1, room_other.shape)
    m, _ = jax.lax.fori_loop(0, _bisection_steps(S), halve, (low, high))
    before = r < m[..., None]
    placed = room_other * m.astype(dtype) + jnp.sum(jnp.where(before, delta, 0.0), axis=-1)
    room_m = room_other + jnp.sum(jnp.where(r == m[..., None], delta, 0.0), axis=-1)
    rest = jnp.clip(budget - placed, 0.0, room_m)
    u_k = u[states]
    return (jnp.sum(lo * u_k, axis=-1) + room_other * U[m] + jnp.sum(jnp.where(before, delta * u_k, 0.0), axis=-1)
            + rest * u_sorted[m])


@jax.jit  # as extended_value_iteration
def sparse_extended_value_iteration(
    states: jax.Array,
    lo: jax.Array,
    hi: jax.Array,
    room_other: jax.Array,
    rewards: jax.Array,
    state_mask: jax.Array,
    action_mask: jax.Array,
    *,
    u0: jax.Array | None = None,
    tol: float | jax.Array = 1e-3,
    max_iter: int = 100_000,
    aperiodicity: float | jax.Array = 0.5,
    active: bool | jax.Array = True,
) -> PlanResult:
    """:func:`extended_value_iteration` with the boxes given on each pair's slots
    (:func:`sparse_optimistic_expectation`): the same iteration and stopping rule, ``O(S log S + S A K log S)`` per
    sweep. The optimistic values agree with the dense ones up to rounding (sums in another order)."""
    u0 = jnp.zeros(rewards.shape[:1], rewards.dtype) if u0 is None else u0

    def backup(u):
        return rewards + sparse_optimistic_expectation(u, states, lo, hi, room_other, state_mask)

    return relative_value_iteration(
        backup, u0, state_mask, action_mask, discount=1.0, tol=tol, max_iter=max_iter, aperiodicity=aperiodicity,
        active=active,
    )


# ---------------------------------------------------------------------------------------------------------------
# Reference mode (docs/agents.md, "Reference mode"): the reference's extended value iteration
# ---------------------------------------------------------------------------------------------------------------


def colosseum_optimistic_kernel(p_hat: jax.Array, width: jax.Array, u: jax.Array, state_mask: jax.Array) -> jax.Array:
    """The reference's optimistic next-state distributions ``[..., S]`` for one ordering of the states by ``u``.

    With ``b`` the last real state in increasing order of ``u`` (ties: the higher index last, so ``u = 0`` gives the
    last real state) and ``m = min(1, p_hat(b) + width / 2)`` (``width [...]``, one per pair): if ``m = 1`` the point
    mass on ``b``; otherwise ``p_hat`` with ``p(b) = m`` and the excess ``m - p_hat(b)`` removed from the other states
    in increasing order of ``u``, each down to at most 0 (an L1-style shift of mass onto the best state).
    """
    S = u.shape[-1]
    idx = jnp.arange(S)
    key = jnp.where(state_mask, u, -jnp.inf)
    precedes = (key[:, None] < key[None, :]) | ((key[:, None] == key[None, :]) & (idx[:, None] < idx[None, :]))
    best = jnp.argmax(jnp.sum(precedes, axis=0))  # the state every other state precedes
    on_best = idx == best
    p_best = p_hat[..., best]
    m = jnp.minimum(1.0, p_best + width / 2.0)
    excess = (m - p_best)[..., None]
    before = p_hat @ precedes.astype(p_hat.dtype)  # mass of the states walked before each state
    shifted = p_hat - jnp.clip(excess - before, 0.0, p_hat)
    shifted = jnp.where(on_best, m[..., None], shifted)
    return jnp.where((m >= 1.0)[..., None], on_best.astype(p_hat.dtype), shifted)


@jax.jit  # as extended_value_iteration
def colosseum_extended_value_iteration(
    p_hat: jax.Array,
    width: jax.Array,
    rewards: jax.Array,
    state_mask: jax.Array,
    action_mask: jax.Array,
    *,
    tol: float | jax.Array = 1e-3,
    max_iter: int = 1_000_000,
    active: bool | jax.Array = True,
) -> PlanResult:
    """The reference's extended value iteration (docs/agents.md §3), from ``u = 0``.

    Every sweep: ``Q(s, a) = r~(s, a) + p~(s, a) . u - u(s)`` with :func:`colosseum_optimistic_kernel` of the current
    ordering, and ``u'(s) = Q(s, a) + u(s)`` of the last action ``a`` (in index order) that exceeds the running
    maximum or comes within ``tol`` of it; stop when ``span(u' - u) < tol`` with the ``Q`` of that sweep. No
    aperiodicity transform: on a periodic optimistic chain it runs ``max_iter`` sweeps and reports
    ``converged = False``. ``u`` is shifted to ``min u = 0`` after each sweep (the ordering and ``Q`` do not change).
    """
    dtype = rewards.dtype
    inf = jnp.asarray(jnp.inf, dtype)

    def body(c):
        u, _, _, _, _, i = c
        Q = rewards + jnp.sum(colosseum_optimistic_kernel(p_hat, width, u, state_mask) * u, axis=-1) - u[:, None]
        run = jnp.full(u.shape, -inf)
        for a in range(Q.shape[-1]):
            v = Q[:, a] + u
            take = action_mask[a] & ((run == -inf) | (v > run) | (jnp.abs(v - run) < tol))
            run = jnp.where(take, v, run)
        d = run - u
        lo = jnp.min(jnp.where(state_mask, d, inf))
        hi = jnp.max(jnp.where(state_mask, d, -inf))
        u_next = jnp.where(hi - lo < tol, u, run - jnp.min(jnp.where(state_mask, run, inf)))
        return jnp.where(state_mask, u_next, 0.0), Q, lo, hi, hi - lo, i + 1

    def cond(c):
        *_, err, i = c
        return (err >= tol) & (i < max_iter) & active

    S, A = rewards.shape
    init = (jnp.zeros((S,), dtype), jnp.zeros((S, A), dtype), -inf, inf, inf, jnp.asarray(0, jnp.int32))
    u, Q, lo, hi, err, it = jax.lax.while_loop(cond, body, init)
    return PlanResult(Q=Q, u=u, gain_lower=lo, gain_upper=hi, iterations=it, converged=err < tol)
