"""Greedy action selection shared by the tabular agents (agents.md §0, "greedy actor")."""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["greedy_action"]


def greedy_action(key: jax.Array, q: jax.Array, action_mask: jax.Array) -> jax.Array:
    """``argmax_a q[a]`` over the valid actions, ties broken uniformly at random with ``key``.

    Like the reference's Q-values actor, exact ties (e.g. unvisited pairs with identical optimistic values) are
    resolved at random rather than towards the lowest index. A padded action is never returned: if no valid action
    compares as a maximiser (``q`` holds NaN), the choice is uniform over the valid actions.
    """
    q = jnp.where(action_mask, q, -jnp.inf)
    tied = (q >= jnp.max(q)) & action_mask
    tied = jnp.where(jnp.any(tied), tied, action_mask)
    u = jax.random.uniform(key, q.shape)
    return jnp.argmax(jnp.where(tied, u, -1.0)).astype(jnp.int32)
