"""The estimated kernel of a model-based agent on the pairs' observed next states (paper §3.3; docs/agents.md §3).

A continuous model-based agent's policy estimate (for regret) is greedy in the discounted optimal values of its
estimated MDP, recomputed at every log. Its kernel is, per pair, a distribution on the next states observed so far
plus a part spread uniformly over the real states (UCRL2: the empirical kernel, uniform for an unvisited pair; PSRL:
the Dirichlet posterior mean, whose ``1/S`` prior is such a uniform part):

    P(s' | s, a) = sum_k probs[s, a, k] [s' = states[s, a, k]] + uniform[s, a] / S_real   (s' real).

No pair has more observed next states than the MDP has successors, ``K`` (``MDPSpec.max_successors``), so the counts
live in ``K`` slots per pair (:class:`SuccessorCounts`, filled in order of first observation) and a Bellman backup
costs ``O(S A K)`` instead of the dense ``O(S A S)``. At the benchmark's largest MDP (MiniGridRooms, 948 states,
``K = 4``) the dense policy estimate took 124 ms a log per member on the 2-core CPU, the value iteration's ~600 dense
sweeps most of it (docs/benchmarks/continuous_indicators.md, "Sparse policy estimate").
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from agents.tabular_common import copy_action_zero
from jaxmdp import dynamic_programming as dp

__all__ = [
    "SuccessorCounts",
    "empty_counts",
    "record",
    "dense_counts",
    "SparseKernel",
    "expected_next_values",
    "policy_matrix",
    "discounted_greedy_policy",
]


class SuccessorCounts(struct.PyTreeNode):
    """Visit counts of the observed next states: ``states[S, A, K]`` (int32) and ``counts[S, A, K]`` (int32, 0 for
    an empty slot; the filled slots of a pair come first, in order of first observation), and ``overflowed``, set
    when a pair met more than ``K`` distinct next states: then the slots miss some counts and the agent must use its
    dense counts (impossible with ``K`` from :func:`~jaxmdp.experiment.agent_interface.spec_of`)."""

    states: jax.Array
    counts: jax.Array
    overflowed: jax.Array


def empty_counts(n_states: int, n_actions: int, max_successors: int | None) -> SuccessorCounts:
    """No observation yet; ``max_successors`` ``K`` slots per pair (``None``: ``n_states``, which never overflows)."""
    K = n_states if max_successors is None else min(max_successors, n_states)
    return SuccessorCounts(
        states=jnp.zeros((n_states, n_actions, K), jnp.int32),
        counts=jnp.zeros((n_states, n_actions, K), jnp.int32),
        overflowed=jnp.zeros((), bool),
    )


def record(table: SuccessorCounts, s: jax.Array, a: jax.Array, s_next: jax.Array) -> SuccessorCounts:
    """Count the transition ``(s, a, s_next)``: in the slot already holding ``s_next``, else in the pair's first empty
    slot (``O(K)``)."""
    states, counts = table.states[s, a], table.counts[s, a]
    used = counts > 0
    match = used & (states == s_next)
    found = jnp.any(match)
    free = ~used
    j = jnp.where(found, jnp.argmax(match), jnp.argmax(free))
    fits = found | jnp.any(free)
    return table.replace(
        states=table.states.at[s, a, j].set(jnp.where(fits, s_next, states[j])),
        counts=table.counts.at[s, a, j].add(fits.astype(jnp.int32)),
        overflowed=table.overflowed | ~fits,
    )


def dense_counts(table: SuccessorCounts) -> jax.Array:
    """The same counts as a dense ``[S, A, S]`` table."""
    S, A, K = table.states.shape
    rows = jnp.zeros((S, A, S), jnp.int32)
    s, a, _ = jnp.meshgrid(jnp.arange(S), jnp.arange(A), jnp.arange(K), indexing="ij")
    return rows.at[s, a, table.states].add(table.counts)


class SparseKernel(struct.PyTreeNode):
    """``P(s'|s, a) = sum_k probs[s, a, k] [s' = states[s, a, k]] + uniform[s, a] state_mask[s'] / S_real`` (module
    docstring): ``states``/``probs`` ``[S, A, K]``, ``uniform[S, A]``, ``state_mask[S]``."""

    states: jax.Array
    probs: jax.Array
    uniform: jax.Array
    state_mask: jax.Array

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


def discounted_greedy_policy(kernel: SparseKernel, R: jax.Array, discount: Any, action_mask: jax.Array) -> jax.Array:
    """Greedy one-hot ``[S, A]`` policy (lowest-index ties) of the ``discount``-discounted optimal values of
    ``(kernel, R[S, A])``, padded actions mirroring action 0: :func:`~agents.tabular_common.discounted_greedy_policy`
    (value iteration to ``1e-3``, then policy iteration with exact linear-solve evaluations,
    :func:`~jaxmdp.dynamic_programming.solve_discounted`) with ``O(S A K)`` backups. The same policy-evaluation
    systems as the dense route; the backups sum in another order, so near-ties can resolve differently."""
    kernel = kernel.copy_action_zero(action_mask)
    R = copy_action_zero(R, action_mask)
    all_states = jnp.ones(R.shape[:1], bool)
    all_actions = jnp.ones(R.shape[1:], bool)

    def backup(V: jax.Array) -> jax.Array:
        return R + discount * expected_next_values(kernel, V)

    vi = dp.relative_value_iteration(
        backup, jnp.zeros(R.shape[:1], R.dtype), all_states, all_actions, discount=discount, tol=1e-3,
        max_iter=10_000,
    )

    def evaluate(pi: jax.Array) -> jax.Array:
        return dp.discounted_chain_values(policy_matrix(kernel, pi), jnp.sum(pi * R, axis=-1), discount)

    def improve(pi: jax.Array, V: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        Q = backup(V)
        return Q, jnp.max(Q, axis=-1) - jnp.sum(pi * Q, axis=-1), dp.greedy(Q)

    res = dp.policy_iteration_by(evaluate, improve, dp.greedy(vi.Q))
    return dp.greedy(res.Q, action_mask)
