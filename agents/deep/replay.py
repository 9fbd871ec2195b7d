"""Uniform experience replay: a fixed-capacity ring buffer of transitions kept in the agent state (Mnih et al. 2015,
"Human-level control through deep reinforcement learning", Methods: experience replay).

The buffer is flashbax's item buffer (``flashbax.make_item_buffer``): its state is a pytree of arrays
(``experience`` with a leading ``[1, capacity]`` prefix, ``current_index``, ``is_full``), so it lives inside an
agent state that the runner vmaps over members, scans over steps and checkpoints leaf by leaf. Adding writes item
``n`` to slot ``n mod capacity`` (the oldest item is overwritten once the buffer is full); sampling draws
``batch_size`` items uniformly, with replacement, from the filled part only. Checked under ``jit``, ``vmap`` over 16
members and ``lax.scan`` with wrap-around (tests/test_dqn.py). Its one constraint, ``batch_size <= capacity``, is
enforced by the agents' ``check_hparams``.
"""

from __future__ import annotations

from typing import Any

import flashbax
import jax
import jax.numpy as jnp

__all__ = ["ReplayState", "make", "size"]

ReplayState = flashbax.buffers.trajectory_buffer.TrajectoryBufferState


def make(capacity: int, batch_size: int) -> Any:
    """The buffer's pure functions for static sizes: ``init(example) -> state``, ``add(state, item) -> state`` and
    ``sample(state, key).experience`` (a pytree of ``[batch_size, ...]`` arrays).

    ``min_length=1``: whether the buffer holds enough items to learn from is the agent's decision
    (:func:`size`), so ``min_replay`` can stay a traced hyperparameter.
    """
    return flashbax.make_item_buffer(max_length=capacity, min_length=1, sample_batch_size=batch_size)


def size(state: ReplayState) -> jax.Array:
    """Number of items held: the items added so far, at most the capacity."""
    capacity = jax.tree.leaves(state.experience)[0].shape[1]
    return jnp.where(state.is_full, capacity, state.current_index).astype(jnp.int32)
