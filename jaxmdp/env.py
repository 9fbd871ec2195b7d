"""Functional environment API in the style of gymnax 1.0: ``reset`` and ``step`` with the MDP as the params pytree.

Observations are state indices (tabular). Episodes (families.md §1.8): ``reset`` draws ``s0 ~ P0`` and sets the
in-episode step ``h = 0``; every ``step`` takes one action, so an episode has exactly ``horizon`` actions taken at
``h = 0 .. horizon - 1``, each earning a reward. The step whose action is the last one of the episode reports
``terminated = True``; the environment then resets itself: the returned observation and state are those of a fresh
episode, and ``info["final_observation"]`` is the state the last action reached (never observed by the agent in the
reference). Continuous MDPs never terminate and ``h`` counts steps since the reset. ``truncated`` is always False
(there is no time limit other than the horizon).

Rewards are drawn from the transition's distribution (``Beta`` or point mass, see :class:`~jaxmdp.MDP`). Everything
is jittable and vmaps over keys, states and stacked MDPs.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from jaxmdp.beta_sampling import sample_beta
from jaxmdp.mdp import MDP

__all__ = ["EnvState", "reset", "step", "sample_action", "sample_next_state", "sample_reward"]


class EnvState(struct.PyTreeNode):
    """Environment state: the current state index and the in-episode step ``h``."""

    state: jax.Array
    h: jax.Array


def _sample_start(key: jax.Array, mdp: MDP) -> jax.Array:
    cdf = jnp.cumsum(mdp.P0)
    u = jax.random.uniform(key, dtype=mdp.dtype) * cdf[-1]
    return jnp.minimum(jnp.sum(cdf <= u), mdp.n_states - 1).astype(jnp.int32)


def sample_action(key: jax.Array, mdp: MDP) -> jax.Array:
    """A uniformly random valid action. Uses one uniform draw, so padding an MDP does not change the draw."""
    n_valid = jnp.sum(mdp.action_mask)
    a = jnp.floor(jax.random.uniform(key, dtype=jnp.float32) * n_valid).astype(jnp.int32)
    return jnp.minimum(a, n_valid - 1)


def sample_next_state(key: jax.Array, mdp: MDP, state: jax.Array, action: jax.Array) -> jax.Array:
    """Draw ``s' ~ P(. | state, action)`` by inverse CDF over the successor list (``O(K)``)."""
    p = mdp.succ_p[state, action]
    cdf = jnp.cumsum(p)
    u = jax.random.uniform(key, dtype=mdp.dtype) * cdf[-1]
    k = jnp.minimum(jnp.sum(cdf <= u), p.shape[-1] - 1)
    return mdp.succ[state, action, k].astype(jnp.int32)


def sample_reward(
    key: jax.Array,
    mdp: MDP,
    state: jax.Array,
    action: jax.Array,
    next_state: jax.Array,
    *,
    stochastic_rewards: bool = True,
) -> jax.Array:
    """Draw the reward of ``(state, action, next_state)``: Beta(mean*conc, (1-mean)*conc) if ``conc > 0``, else mean.

    Beta draws use :func:`jaxmdp.beta_sampling.sample_beta` (exact; several times faster than ``jax.random.beta``
    under ``vmap``, where the reward draw dominated the cost of a step). Under ``vmap`` both branches are computed
    for every member, so a caller that knows (on the host) that no transition has a Beta reward can pass the static
    ``stochastic_rewards=False`` to skip the draw; the result is then the mean, which is exact for such MDPs.
    """
    mean = mdp.reward_mean[state, action, next_state]
    if not stochastic_rewards:
        return mean
    conc = mdp.reward_conc[state, action, next_state]
    stochastic = conc > 0
    alpha = jnp.where(stochastic, mean * conc, 1.0)
    beta = jnp.where(stochastic, (1.0 - mean) * conc, 1.0)
    draw = sample_beta(key, alpha, beta, dtype=mdp.dtype)
    return jnp.where(stochastic, draw, mean)


def reset(key: jax.Array, mdp: MDP) -> tuple[jax.Array, EnvState]:
    """Start an episode: ``s0 ~ P0``, ``h = 0``. Returns ``(obs, state)``."""
    s0 = _sample_start(key, mdp)
    return s0, EnvState(state=s0, h=jnp.zeros((), jnp.int32))


def step(
    key: jax.Array, state: EnvState, action: jax.Array, mdp: MDP, *, stochastic_rewards: bool = True
) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, jax.Array, dict[str, Any]]:
    """Take ``action``: returns ``(obs, state, reward, terminated, truncated, info)`` with auto-reset.

    ``info`` holds ``final_observation`` (the state reached by this action, before any reset) and ``discount``
    (0 on termination, else 1). ``stochastic_rewards=False`` (static) promises that every reward is a point mass
    and skips the Beta draw (see :func:`sample_reward`).
    """
    k_next, k_reward, k_reset = jax.random.split(key, 3)
    action = jnp.asarray(action, jnp.int32)
    s_next = sample_next_state(k_next, mdp, state.state, action)
    reward = sample_reward(k_reward, mdp, state.state, action, s_next, stochastic_rewards=stochastic_rewards)
    h_next = state.h + 1
    terminated = (h_next >= mdp.horizon) if mdp.episodic else jnp.zeros((), bool)
    s_reset = _sample_start(k_reset, mdp)
    new_state = EnvState(
        state=jnp.where(terminated, s_reset, s_next),
        h=jnp.where(terminated, 0, h_next).astype(jnp.int32),
    )
    info = {"final_observation": s_next, "discount": 1.0 - terminated.astype(mdp.dtype)}
    return new_state.state, new_state, reward, terminated, jnp.zeros((), bool), info
