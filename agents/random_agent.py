"""The uniformly random agent, episodic and continuous (docs/agents.md §6).

It acts uniformly over the valid actions and its policy estimate is the uniform policy (``[S, A]`` continuous,
``[H, S, A]`` episodic), so its expected regret is exactly the "random" baseline of docs/measures.md §6.3 (episodic: the
paper's ``P0``-averaged indicator; continuous: when the uniform policy's chain has one recurrent class). The policy
never changes (``fixed_policy``), so the runner evaluates it once per run.

Difference from the reference: the reference's class is abstract (its per-step update is missing, [quirk]) and
pre-draws blocks of actions from a ``RandomState``; here the update is a no-op and every action comes from the
step's key.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmdp import struct
from jaxmdp._asserts import assert_observation, assert_transition
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, RunnerHints, Transition
from jaxmdp.sampling import fused_random

__all__ = ["RandomHParams", "RandomState", "RANDOM_EPISODIC", "RANDOM_CONTINUOUS"]


class RandomHParams(struct.PyTreeNode):
    """The random agent has no hyperparameters."""


class RandomState(struct.PyTreeNode):
    """The valid actions and the policy's shape (``H`` static, ``None`` when continuous)."""

    action_mask: jax.Array
    n_states: int = struct.field(pytree_node=False)
    H: int | None = struct.field(pytree_node=False)


def init(key: jax.Array, spec: MDPSpec, hparams: RandomHParams) -> RandomState:
    del key, hparams
    return RandomState(action_mask=spec.action_mask, n_states=spec.n_states, H=spec.H)


def act(key: jax.Array, state: RandomState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """The ``k``-th valid action with ``k`` uniform on ``0 .. n_valid - 1`` (``obs`` ignored: a state index or an
    emission)."""
    assert_observation(obs, h, obs_shape=None)
    n_valid = jnp.sum(state.action_mask)
    k = jnp.minimum(jnp.floor(fused_random.uniform(key) * n_valid).astype(jnp.int32), n_valid - 1)
    return jnp.argmax(jnp.cumsum(state.action_mask) > k).astype(jnp.int32)


def update(state: RandomState, transition: Transition) -> RandomState:
    assert_transition(transition, obs_shape=None)
    return state


def policy(state: RandomState) -> jax.Array:
    """``pi(a|s) = 1 / n_valid`` on the valid actions."""
    w = state.action_mask.astype(jnp.float32)
    shape = (state.n_states, w.shape[0]) if state.H is None else (state.H, state.n_states, w.shape[0])
    return jnp.broadcast_to(w / jnp.sum(w), shape)


def _make(episodic: bool) -> Agent:
    return Agent(
        name="random_episodic" if episodic else "random_continuous",
        episodic=episodic,
        default_hparams=RandomHParams(),
        init=init,
        act=act,
        update=update,
        policy=policy,
        observation="any",
        hints=RunnerHints(fixed_policy=True),
    )


RANDOM_EPISODIC = _make(True)
RANDOM_CONTINUOUS = _make(False)
