"""The estimated kernel of a model-based agent on the pairs' observed next states (paper §3.3; docs/agents.md §3).

A continuous model-based agent's policy estimate (for regret) is greedy in the discounted optimal values of its
estimated MDP, recomputed at every log. Its kernel is, per pair, a distribution on the next states observed so far
plus a part spread uniformly over the real states (UCRL2: the empirical kernel, uniform for an unvisited pair; PSRL:
the Dirichlet posterior mean, whose ``1/S`` prior is such a uniform part):

    P(s' | s, a) = sum_k probs[s, a, k] [s' = states[s, a, k]] + uniform[s, a] / S_real   (s' real).

No pair has more observed next states than the MDP has successors, ``K`` (``MDPSpec.max_successors``), so the counts
live in ``K`` slots per pair (:class:`SuccessorCounts`, filled in order of first observation) and a Bellman backup
costs ``O(S A K)`` instead of the dense ``O(S A S)``: at the benchmark's largest MDPs (``K = 4`` successors of
hundreds of states) the value iteration's hundreds of dense sweeps would dominate every log (docs/performance.md,
Continuous indicators).

The observed next states are among the MDP's successors, so in a state order where every transition of the MDP joins
positions at most ``w`` apart (``MDPSpec.state_order``, :func:`jaxmdp.gth.band_order`) the observed part of a policy's
kernel is banded, and the uniform part is one rank-one term. A policy's evaluation is then a banded elimination
(:func:`~jaxmdp.dynamic_programming.discounted_chain_values_banded`, ``O(S w^2)``) and a Sherman-Morrison correction
instead of a dense ``O(S^3)`` solve (:func:`policy_values`).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from agents.tabular_common import copy_action_zero, only_if
from jaxmdp import dynamic_programming as dp
from jaxmdp import struct

__all__ = [
    "SuccessorCounts",
    "empty_counts",
    "record",
    "scatter_slots",
    "dense_counts",
    "with_dense_counts",
    "SparseKernel",
    "positions",
    "expected_next_values",
    "policy_matrix",
    "policy_values",
    "discounted_greedy_policy",
    "warm_greedy_policy",
    "greedy_policy_phases",
]


class SuccessorCounts(struct.PyTreeNode):
    """Visit counts of the observed next states: ``states[S, A, K]`` (int32) and ``counts[S, A, K]`` (int32, 0 for
    an empty slot; the filled slots of a pair come first, in order of first observation), and ``overflowed``, set
    when a pair met more than ``K`` distinct next states: then the slots miss the extra next states' counts (impossible
    with ``K`` from :func:`~jaxmdp.experiment.agent_interface.spec_of`; the agents report it as a diagnostic)."""

    states: jax.Array
    counts: jax.Array
    overflowed: jax.Array
    #: The MDP's band order (``[S]``) and its static bandwidth (``MDPSpec.state_order``, ``MDPSpec.bandwidth``), or
    #: ``None``: passed on to :class:`SparseKernel` for banded policy evaluations.
    order: jax.Array | None = None
    bandwidth: int | None = struct.field(pytree_node=False, default=None)


def empty_counts(
    n_states: int, n_actions: int, max_successors: int | None, state_order: jax.Array | None = None,
    bandwidth: int | None = None,
) -> SuccessorCounts:
    """No observation yet; ``max_successors`` ``K`` slots per pair (``None``: ``n_states``, which never overflows);
    ``state_order`` and ``bandwidth``: the MDP's band order (both or neither, e.g. from the agent's
    :class:`~jaxmdp.experiment.agent_interface.MDPSpec`)."""
    if (state_order is None) != (bandwidth is None):
        raise ValueError("state_order and bandwidth go together: give both (jaxmdp.gth.band_order) or neither")
    K = n_states if max_successors is None else min(max_successors, n_states)
    return SuccessorCounts(
        states=jnp.zeros((n_states, n_actions, K), jnp.int32),
        counts=jnp.zeros((n_states, n_actions, K), jnp.int32),
        overflowed=jnp.zeros((), bool),
        order=None if state_order is None else jnp.asarray(state_order, jnp.int32),
        bandwidth=bandwidth,
    )


def record(
    table: SuccessorCounts, s: jax.Array, a: jax.Array, s_next: jax.Array, count: jax.Array | bool = True
) -> SuccessorCounts:
    """Count the transition ``(s, a, s_next)``: in the slot already holding ``s_next``, else in the pair's first empty
    slot (``O(K)``). ``count`` False (traced or not) leaves the counts as they are: an agent that skips a transition
    pays ``O(K)`` for it, not a select over every slot."""
    states, counts = table.states[s, a], table.counts[s, a]
    used = counts > 0
    match = used & (states == s_next)
    found = jnp.any(match)
    free = ~used
    j = jnp.where(found, jnp.argmax(match), jnp.argmax(free))
    fits = found | jnp.any(free)
    count = jnp.asarray(count, bool)
    add = fits & count
    return table.replace(
        states=table.states.at[s, a, j].set(jnp.where(add, s_next, states[j])),
        counts=table.counts.at[s, a, j].add(add.astype(jnp.int32)),
        overflowed=table.overflowed | (~fits & count),
    )


def scatter_slots(states: jax.Array, values: jax.Array, n_states: int) -> jax.Array:
    """Dense rows ``[..., n_states]`` of per-slot ``values[..., K]`` at next states ``states[..., K]``: ``row[s'] =
    sum_k values[k] [states[k] = s']`` (any leading axes, e.g. a batch of members; ``O(n K)`` writes into zeros)."""
    *lead, K = states.shape
    n = int(np.prod(lead, dtype=np.int64))
    rows = jnp.zeros((n, n_states), values.dtype)
    rows = rows.at[jnp.arange(n)[:, None], states.reshape(n, K)].add(values.reshape(n, K))
    return rows.reshape(*lead, n_states)


def dense_counts(table: SuccessorCounts) -> jax.Array:
    """The same counts as a dense ``[..., S, A, S]`` table (any leading axes: a batch of tables)."""
    return scatter_slots(table.states, table.counts, table.states.shape[-3])


def with_dense_counts(table: SuccessorCounts, counts: jax.Array) -> SuccessorCounts:
    """``table`` (its slot count ``K`` and band order) holding dense counts ``counts[S, A, S]`` instead: each pair's
    next states with a positive count in index order (the order of first observation is not in dense counts), then
    empty slots; ``overflowed`` if a pair has more than ``K``. The inverse of :func:`dense_counts` up to the slots'
    order, for states built from counts (tests, benchmarks) rather than by :func:`record`."""
    counts = jnp.asarray(counts, jnp.int32)
    K = table.states.shape[-1]
    seen = counts > 0
    first = jnp.argsort(~seen, axis=-1, stable=True)[..., :K]
    slot_counts = jnp.take_along_axis(counts, first, axis=-1)
    return table.replace(
        states=jnp.where(slot_counts > 0, first, 0).astype(jnp.int32),
        counts=slot_counts,
        overflowed=jnp.any(jnp.sum(seen, axis=-1) > K),
    )


class SparseKernel(struct.PyTreeNode):
    """``P(s'|s, a) = sum_k probs[s, a, k] [s' = states[s, a, k]] + uniform[s, a] state_mask[s'] / S_real`` (module
    docstring): ``states``/``probs`` ``[S, A, K]``, ``uniform[S, A]``, ``state_mask[S]``; ``order`` (``[S]``) and
    static ``bandwidth``: a state order in which every slot of positive probability joins positions at most
    ``bandwidth`` apart (the MDP's band order, :attr:`SuccessorCounts.order`), or ``None``."""

    states: jax.Array
    probs: jax.Array
    uniform: jax.Array
    state_mask: jax.Array
    order: jax.Array | None = None
    bandwidth: int | None = struct.field(pytree_node=False, default=None)

    @classmethod
    def of(cls, table: SuccessorCounts, probs: jax.Array, uniform: jax.Array, state_mask: jax.Array) -> "SparseKernel":
        """The kernel on ``table``'s observed next states, with its band order: ``probs[S, A, K]`` at the slots and
        ``uniform[S, A]``."""
        return cls(states=table.states, probs=probs, uniform=uniform, state_mask=state_mask, order=table.order,
                   bandwidth=table.bandwidth)

    def in_band(self) -> jax.Array:
        """Whether every slot of positive probability joins positions at most ``bandwidth`` apart in ``order``
        (``O(S A K)``; True without an order)."""
        if self.order is None:
            return jnp.ones((), bool)
        pos = positions(self.order)
        return jnp.all((self.probs == 0) | (jnp.abs(pos[:, None, None] - pos[self.states]) <= self.bandwidth))

    def copy_action_zero(self, action_mask: jax.Array) -> "SparseKernel":
        """Padded actions' rows replaced by action 0's (:func:`~agents.tabular_common.copy_action_zero`)."""
        return self.replace(
            states=copy_action_zero(self.states, action_mask),
            probs=copy_action_zero(self.probs, action_mask),
            uniform=copy_action_zero(self.uniform, action_mask),
        )


def _uniform_row(kernel: SparseKernel, dtype: Any) -> jax.Array:
    """``state_mask / S_real``: the uniform distribution over the real states, as the dense estimates write it."""
    return kernel.state_mask.astype(dtype) / jnp.sum(kernel.state_mask)


def expected_next_values(kernel: SparseKernel, V: jax.Array) -> jax.Array:
    """``E[V(s') | s, a]`` for every pair, ``[S, A]``: ``sum_k probs V[states] + uniform mean_real(V)``."""
    mean = jnp.sum(_uniform_row(kernel, V.dtype) * V)
    return jnp.sum(kernel.probs * V[kernel.states], axis=-1) + kernel.uniform * mean


def policy_matrix(kernel: SparseKernel, pi: jax.Array) -> jax.Array:
    """Dense ``P_pi[s, s'] = sum_a pi(a|s) P(s'|s, a)`` of a policy ``pi[S, A]`` (``O(S A K + S^2)``)."""
    S, A, K = kernel.states.shape
    dtype = kernel.probs.dtype
    weight = pi.astype(dtype)[..., None] * kernel.probs
    rows = jnp.broadcast_to(jnp.arange(S)[:, None, None], (S, A, K))
    sparse = jnp.zeros((S, S), dtype).at[rows, kernel.states].add(weight)
    return sparse + jnp.sum(pi * kernel.uniform, axis=-1)[:, None] * _uniform_row(kernel, dtype)


def positions(order: jax.Array) -> jax.Array:
    """``pos[s]``: the position of state ``s`` in ``order`` (the inverse permutation)."""
    S = order.shape[0]
    return jnp.zeros((S,), jnp.int32).at[order].set(jnp.arange(S, dtype=jnp.int32))


def policy_values(kernel: SparseKernel, pi: jax.Array, R: jax.Array, discount: Any) -> jax.Array:
    """Discounted values ``V = (I - gamma P_pi)^{-1} r_pi`` of a policy ``pi[S, A]`` (Puterman 1994 §6.1).

    Without a band order: :func:`policy_matrix` and a dense solve (``O(S^3)``). With one (``kernel.order``, which
    must hold, :meth:`SparseKernel.in_band`): ``P_pi = B + u m^T``, with ``B`` the slots' part (banded in the order),
    ``u[s] = sum_a pi(a|s) uniform[s, a]`` its missing row mass and ``m`` the uniform distribution on the real
    states. With ``x, y, z = (I - gamma B)^{-1} [r_pi, u, 1]`` (one banded elimination,
    :func:`~jaxmdp.dynamic_programming.discounted_chain_values_banded`), Sherman-Morrison gives ``V = x + gamma y
    (m.x) / (1 - gamma m.y)``; the denominator is ``(1 - gamma) m.z`` (from ``(I - gamma B) 1 = (1 - gamma) 1 + gamma
    u``), a product of positive numbers, at least ``1 - gamma``. ``O(S A K + S w^2)`` plus the ``S x S`` matrix's
    writes."""
    dtype = kernel.probs.dtype
    r = jnp.sum(pi * R, axis=-1)
    if kernel.order is None:
        return dp.discounted_chain_values(policy_matrix(kernel, pi), r, discount)
    discount = jnp.asarray(discount, dtype)
    order, pos = kernel.order, positions(kernel.order)
    # Row and column i: state order[i].
    B = dp.successor_policy_matrix(pos[kernel.states][order], kernel.probs[order], pi.astype(dtype)[order])
    u = jnp.sum(pi * kernel.uniform, axis=-1)[order]
    m = _uniform_row(kernel, dtype)[order]
    x, y, z = dp.discounted_chain_values_banded(
        B, u, jnp.stack([r[order], u, jnp.ones_like(u)], axis=1), discount, kernel.bandwidth
    ).T
    # Element-wise sums, not dot products: an accelerator may multiply float32 dot operands in reduced
    # precision.
    V = x + discount * y * (jnp.sum(m * x) / ((1.0 - discount) * jnp.sum(m * z)))
    return V[pos]


def discounted_greedy_policy(kernel: SparseKernel, R: jax.Array, discount: Any, action_mask: jax.Array) -> jax.Array:
    """Greedy one-hot ``[S, A]`` policy (lowest-index ties) of the ``discount``-discounted optimal values of
    ``(kernel, R[S, A])``, padded actions mirroring action 0: :func:`~agents.tabular_common.discounted_greedy_policy`
    (value iteration to ``1e-3``, then policy iteration with exact evaluations, :func:`policy_values`) with ``O(S A
    K)`` backups. The same policy-evaluation systems as the dense route; the backups sum in another order, so
    near-ties can resolve differently. With a band order (``kernel.order``) the evaluations are banded; a kernel
    outside its band (a wrong hint) is solved densely instead, by the members it concerns only."""
    return warm_greedy_policy(kernel, R, discount, action_mask, None)[0]


def warm_greedy_policy(
    kernel: SparseKernel, R: jax.Array, discount: Any, action_mask: jax.Array, u0: jax.Array | None
) -> tuple[jax.Array, jax.Array]:
    """:func:`discounted_greedy_policy` with its value iteration started from ``u0`` (``[S]``; ``None``: zeros), and
    the exact values ``V[S]`` of the returned policy, a start for the next estimate.

    Both phases stop on the same rules from any start (value iteration when ``max_s |T u - u| < 1e-3``, policy
    iteration when no state gains more than ``1e-5 (1 + max|V|)``), so the policy is the same estimate up to those
    tolerances: it can differ from the cold start's only where two policies both pass them. From the exact values
    of the previous log's policy value iteration needs far fewer sweeps than from zeros, with the same policies
    (docs/performance.md, Continuous indicators)."""
    if kernel.order is None:
        return _greedy_policy(kernel, R, discount, action_mask, u0)
    banded = _greedy_policy(kernel, R, discount, action_mask, u0)
    unbanded = lambda k, r, u: _greedy_policy(  # noqa: E731
        k.replace(order=None, bandwidth=None), r, discount, action_mask, u)
    return only_if(~kernel.in_band(), unbanded, banded, kernel, R, u0)


def _greedy_policy(
    kernel: SparseKernel, R: jax.Array, discount: Any, action_mask: jax.Array, u0: jax.Array | None = None
) -> tuple[jax.Array, jax.Array]:
    """:func:`warm_greedy_policy`, banded if ``kernel.order`` is given (which must then hold)."""
    pi, _, res = greedy_policy_phases(kernel, R, discount, action_mask, u0)
    return pi, res.V


def greedy_policy_phases(
    kernel: SparseKernel, R: jax.Array, discount: Any, action_mask: jax.Array, u0: jax.Array | None = None
) -> tuple[jax.Array, dp.PlanResult, dp.ValueIterationResult]:
    """The two phases of the policy estimate (:func:`discounted_greedy_policy`, banded if ``kernel.order`` is given,
    which must then hold): value iteration ``u <- max_a R + discount E[u(s')]`` from ``u0`` (default zeros) until
    ``max_s |T u - u| < 1e-3``, then Howard's policy iteration with exact evaluations from the policy greedy on it.
    Returns the greedy one-hot ``[S, A]`` policy and both phases' results (sweeps, evaluations): a start near the
    optimal values needs fewer sweeps."""
    kernel = kernel.copy_action_zero(action_mask)
    R = copy_action_zero(R, action_mask)
    all_states = jnp.ones(R.shape[:1], bool)
    all_actions = jnp.ones(R.shape[1:], bool)

    def backup(V: jax.Array) -> jax.Array:
        return R + discount * expected_next_values(kernel, V)

    vi = dp.relative_value_iteration(
        backup, jnp.zeros(R.shape[:1], R.dtype) if u0 is None else u0, all_states, all_actions, discount=discount,
        tol=1e-3, max_iter=10_000,
    )

    def evaluate(pi: jax.Array) -> jax.Array:
        return policy_values(kernel, pi, R, discount)

    def improve(pi: jax.Array, V: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        Q = backup(V)
        return Q, jnp.max(Q, axis=-1) - jnp.sum(pi * Q, axis=-1), dp.greedy(Q)

    res = dp.policy_iteration_by(evaluate, improve, dp.greedy(vi.Q))
    return dp.greedy(res.Q, action_mask), vi, res
