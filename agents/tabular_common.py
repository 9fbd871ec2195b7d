"""Pieces shared by the tabular agents: the greedy actor with random tie-breaking and the counts of real states and
actions of a (possibly padded) MDP. Hyperparameter checks are :func:`jaxmdp._checks.check_range` and
:func:`jaxmdp._checks.check_int`."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

__all__ = ["greedy_action", "valid_counts"]


def greedy_action(key: jax.Array, q: jax.Array, action_mask: jax.Array) -> jax.Array:
    """``argmax_a q[a]`` over the valid actions, exact ties broken uniformly at random with ``key``.

    Like the reference's Q-values actor (docs/agents.md §0), exact ties (e.g. unvisited pairs with identical
    optimistic values) are resolved at random rather than towards the lowest index. A padded action is never
    returned: if no valid action compares as a maximiser (``q`` holds NaN), the choice is uniform over the valid
    actions.
    """
    q = jnp.where(action_mask, q, -jnp.inf)
    tied = (q >= jnp.max(q)) & action_mask
    tied = jnp.where(jnp.any(tied), tied, action_mask)
    u = jax.random.uniform(key, q.shape)
    return jnp.argmax(jnp.where(tied, u, -1.0)).astype(jnp.int32)


def valid_counts(state_mask: jax.Array, action_mask: jax.Array, dtype: Any = jnp.float32) -> tuple[jax.Array, jax.Array]:
    """Numbers of real (unpadded) states and actions, as floats."""
    return jnp.sum(state_mask).astype(dtype), jnp.sum(action_mask).astype(dtype)
