"""Pieces shared by the tabular agents: the greedy actor with random tie-breaking, table reads and writes through one
flat index, the counts of real states and actions of a (possibly padded) MDP, the discounted policy estimate of a
model with padded actions, and a computation skipped unless some member of a ``vmap`` needs it.
Hyperparameter checks are :func:`jaxmdp._checks.check_range` and :func:`jaxmdp._checks.check_int`."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

from jaxmdp import dynamic_programming as dp

__all__ = [
    "copy_action_zero",
    "discounted_greedy_policy",
    "first_argmax",
    "greedy_action",
    "greedy_action_single_draw",
    "max_and_first_argmax",
    "only_if",
    "read_at",
    "row_max",
    "valid_counts",
    "write_at",
]


# Up to this many actions the argmax of :func:`greedy_action` is unrolled into elementwise passes: XLA's variadic
# argmax reduction is several times slower on CPU, and every member acts at every step.
_UNROLLED_MAX_ACTIONS = 16
# The same for PSRL continuous's best of ``psi`` candidates per pair (60 at the benchmark's largest MDPs), unrolled
# into elementwise passes over the pairs (:func:`max_and_first_argmax`).
_UNROLLED_MAX_CANDIDATES = 128


def row_max(x: jax.Array) -> jax.Array:
    """``jnp.max(x, axis=-1)`` (NaN propagates), unrolled for few entries."""
    if x.shape[-1] > _UNROLLED_MAX_ACTIONS:
        return jnp.max(x, axis=-1)
    best = x[..., 0]
    for a in range(1, x.shape[-1]):
        best = jnp.maximum(best, x[..., a])
    return best


def first_argmax(x: jax.Array) -> jax.Array:
    """``jnp.argmax(x)`` of a 1-D ``x`` without NaN (the first index of the maximum), unrolled for few entries."""
    n = x.shape[-1]
    if n > _UNROLLED_MAX_ACTIONS:
        return jnp.argmax(x).astype(jnp.int32)
    best = row_max(x)
    index = jnp.asarray(n - 1, jnp.int32)
    for a in reversed(range(n - 1)):
        index = jnp.where(x[a] >= best, a, index)
    return index


def max_and_first_argmax(x: jax.Array, axis: int = 0) -> tuple[jax.Array, jax.Array]:
    """``(jnp.max(x, axis), jnp.argmax(x, axis))`` for ``x`` without NaN: the maximum and the lowest index that attains
    it (``int32``), by a running maximum over the entries of ``axis``, unrolled. XLA CPU lowers ``jnp.argmax`` as one
    (value, index) reduction that does not vectorise: over ``[60, 784, 3]`` along the first axis it took 0.33 ms
    (docs/performance.md, Continuous planning). A maximum and then the lowest index equal to it is not a substitute:
    XLA may compute ``x`` again for the second reduction with other roundings, and then no entry equals the
    maximum. Each step here compares and keeps the same value."""
    axis = axis % x.ndim
    n = x.shape[axis]
    if n > _UNROLLED_MAX_CANDIDATES:
        return jnp.max(x, axis=axis), jnp.argmax(x, axis=axis).astype(jnp.int32)
    best = jax.lax.index_in_dim(x, 0, axis, keepdims=False)
    index = jnp.zeros(best.shape, jnp.int32)
    for k in range(1, n):
        value = jax.lax.index_in_dim(x, k, axis, keepdims=False)
        better = value > best
        index = jnp.where(better, jnp.int32(k), index)
        best = jnp.where(better, value, best)
    return best, index


def _flat_index(shape: tuple[int, ...], index: tuple[jax.Array, ...]) -> jax.Array:
    """Row-major position of ``index`` among the leading ``len(index)`` axes of ``shape``."""
    flat = jnp.asarray(index[0], jnp.int32)
    for n, i in zip(shape[1 : len(index)], index[1:]):
        flat = flat * n + i
    return flat


def read_at(table: jax.Array, *index: jax.Array) -> jax.Array:
    """``table[index]`` for in-bounds indices of the leading axes, through one flat index.

    The same numbers as ``table[index]``. Under ``vmap`` over members, XLA's CPU gather with one index dimension is
    cheaper than with two or three, and the agents' updates read and write their tables at every step of every
    member (docs/performance.md, Tabular agents)."""
    k = len(index)
    return table.reshape((-1,) + table.shape[k:])[_flat_index(table.shape, index)]


def write_at(table: jax.Array, value: jax.Array, *index: jax.Array) -> jax.Array:
    """``table.at[index].set(value)`` for in-bounds indices of the leading axes, through one flat index
    (:func:`read_at`)."""
    k = len(index)
    flat = table.reshape((-1,) + table.shape[k:])
    return flat.at[_flat_index(table.shape, index)].set(value).reshape(table.shape)


def greedy_action(key: jax.Array, q: jax.Array, action_mask: jax.Array) -> jax.Array:
    """``argmax_a q[a]`` over the valid actions, exact ties broken uniformly at random with ``key``.

    Like the reference's Q-values actor (docs/agents.md §0), exact ties (e.g. unvisited pairs with identical
    optimistic values) are resolved at random rather than towards the lowest index: each valid action draws a
    float32 uniform and the tied action with the largest draw wins. A padded action is never returned: if no valid
    action compares as a maximiser (``q`` holds NaN), the choice is uniform over the valid actions.
    """
    q = jnp.where(action_mask, q, -jnp.inf)
    tied = (q >= row_max(q)) & action_mask
    tied = jnp.where(jnp.any(tied), tied, action_mask)
    u = jax.random.uniform(key, q.shape, jnp.float32)
    return first_argmax(jnp.where(tied, u, -1.0))


def greedy_action_single_draw(key: jax.Array, q: jax.Array, action_mask: jax.Array) -> jax.Array:
    """:func:`greedy_action` with one uniform draw instead of one per action: with ``n`` tied maximisers, the
    ``floor(u n)``-th of them (in index order) is taken, ``u ~ U[0, 1)``; the same distribution (uniform over the
    ties), a different draw for a given key. Under ``vmap`` a draw of ``A`` uniforms costs several times a scalar
    one, which dominated the per-step cost of the Q-learning agents."""
    q = jnp.where(action_mask, q, -jnp.inf)
    tied = (q >= row_max(q)) & action_mask
    tied = jnp.where(jnp.any(tied), tied, action_mask)
    n = jnp.sum(tied, dtype=jnp.int32)
    k = jnp.minimum((jax.random.uniform(key, (), jnp.float32) * n).astype(jnp.int32), n - 1)
    return first_argmax(jnp.cumsum(tied, dtype=jnp.int32) > k)


def valid_counts(state_mask: jax.Array, action_mask: jax.Array, dtype: Any = jnp.float32) -> tuple[jax.Array, jax.Array]:
    """Numbers of real (unpadded) states and actions, as floats."""
    return jnp.sum(state_mask).astype(dtype), jnp.sum(action_mask).astype(dtype)


def copy_action_zero(x: jax.Array, action_mask: jax.Array) -> jax.Array:
    """``x[:, A, ...]`` (actions on axis 1) with the padded actions' entries replaced by action 0's, as
    :func:`jaxmdp.stack` pads, so that they never change a maximum over actions."""
    mask = action_mask.reshape((1, -1) + (1,) * (x.ndim - 2))
    return jnp.where(mask, x, x[:, :1])


def discounted_greedy_policy(P: jax.Array, R: jax.Array, discount: Any, action_mask: jax.Array) -> jax.Array:
    """Greedy one-hot ``[S, A]`` policy (lowest-index ties) of the ``discount``-discounted optimal values of the
    model ``(P[S, A, S], R[S, A])``, padded actions mirroring action 0: the policy estimate of the continuous
    model-based agents (docs/agents.md §3, §4)."""
    res = dp.solve_discounted(copy_action_zero(P, action_mask), discount, rewards=copy_action_zero(R, action_mask))
    return dp.greedy(res.Q, action_mask)


def only_if(pred: jax.Array, compute: Callable[..., Any], default: Any, *operands: Any) -> Any:
    """``compute(*operands)`` if ``pred`` else ``default`` (same structure), skipping the work when ``pred`` is False.

    A ``while_loop`` that runs its body at most once rather than a ``lax.cond``: under ``vmap`` a ``cond`` with a
    batched predicate becomes a ``select`` that computes both branches for every member, whereas a batched
    ``while_loop`` runs its body only if some member's predicate holds (then for every member, each keeping its own
    result or its ``default``). Alone (one member) it is an ordinary skip. The operands travel in the loop's carry
    and reach ``compute`` through an optimisation barrier together with the loop's flag: a body computed from loop
    invariants alone is hoisted out of the loop by XLA (and then always runs). The carry passes the operands on
    unchanged, so XLA need not copy them into the loop (the barrier's outputs in the carry cost a copy of every
    operand at every call: 37 MB of counts per PSRL backup at 5 members of 784 states)."""

    def body(carry):
        running, ops, _ = carry
        _, shielded = jax.lax.optimization_barrier((running, ops))
        return jnp.zeros((), bool), ops, compute(*shielded)

    return jax.lax.while_loop(lambda carry: carry[0], body, (jnp.asarray(pred, bool), operands, default))[2]
