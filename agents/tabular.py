"""Small pieces shared by the tabular agents of this package: a greedy actor and host-side range checks."""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["greedy_random_ties", "check_interval", "valid_counts"]


def greedy_random_ties(key: jax.Array, q: jax.Array, action_mask: jax.Array) -> jax.Array:
    """``argmax_a q[a]`` over the valid actions with exact ties broken uniformly at random (the reference's greedy
    actor, agents.md §0). Never returns a padded action; if ``q`` holds NaN the choice is uniform over valid ones."""
    q = jnp.where(action_mask, q, -jnp.inf)
    tied = (q == jnp.max(q)) & action_mask
    tied = jnp.where(jnp.any(tied), tied, action_mask)
    u = jax.random.uniform(key, q.shape)
    return jnp.argmax(jnp.where(tied, u, -1.0)).astype(jnp.int32)


def valid_counts(state_mask: jax.Array, action_mask: jax.Array, dtype: Any = jnp.float32) -> tuple[jax.Array, jax.Array]:
    """Numbers of real (unpadded) states and actions, as floats."""
    return jnp.sum(state_mask).astype(dtype), jnp.sum(action_mask).astype(dtype)


def check_interval(
    name: str, value: Any, low: float = -math.inf, high: float = math.inf, *, low_open: bool = False,
    high_open: bool = False,
) -> None:
    """Raise ``ValueError`` unless every entry of ``value`` (a scalar or a stacked grid) is finite and in range."""
    x = np.asarray(value, dtype=np.float64)
    ok = np.isfinite(x) & ((x > low) if low_open else (x >= low)) & ((x < high) if high_open else (x <= high))
    if not np.all(ok):
        bad = x.reshape(-1)[np.argmin(ok.reshape(-1))]
        interval = f"{'(' if low_open else '['}{low}, {high}{')' if high_open else ']'}"
        raise ValueError(f"{name} must be finite and in {interval}; got {bad}")
