"""Functional environment API in the style of gymnax 1.0: ``reset`` and ``step`` with the MDP as the params pytree.

Observations are state indices (tabular). Episodes (docs/families.md §1.8): ``reset`` draws ``s0 ~ P0`` and sets the
in-episode step ``h = 0``; every ``step`` takes one action, so an episode has exactly ``horizon`` actions taken at
``h = 0 .. horizon - 1``, each earning a reward. The step whose action is the last one of the episode reports
``terminated = True``; the environment then resets itself: the returned observation and state are those of a fresh
episode, and ``info["final_observation"]`` is the state the last action reached (never observed by the agent in the
reference). Continuous MDPs never terminate and ``h`` counts steps since the reset. ``truncated`` is always False
(there is no time limit other than the horizon).

Rewards are drawn from the transition's distribution (``Beta`` or point mass, see :class:`~jaxmdp.MDP`). Everything
is jittable and vmaps over keys, states and stacked MDPs.

BlockMDPs (:class:`jaxmdp.BlockMDP`): ``reset`` and ``step`` take one wherever they take an MDP and return its
observations (emission-table row plus a noise draw from ``noise_key(key)``) instead of state indices, with the same
state trajectory, rewards and flags as the underlying MDP for the same keys. ``info["final_observation"]`` is then
the observation of the state reached (the very sample returned when the episode goes on; all zeros past an
episode's end, as the reference), ``info["final_state"]`` that state's index and ``info["state"]`` the index of the
returned observation's state.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from jaxmdp.blockmdp.block_mdp import BlockMDP, noise_key, observe
from jaxmdp.mdp import MDP
from jaxmdp.sampling.beta_sampling import sample_beta

__all__ = ["EnvState", "reset", "step", "sample_action", "sample_next_state", "sample_reward"]


class EnvState(struct.PyTreeNode):
    """Environment state: the current state index and the in-episode step ``h``."""

    state: jax.Array
    h: jax.Array


def _start_from_uniform(u: jax.Array, mdp: MDP) -> jax.Array:
    cdf = jnp.cumsum(mdp.P0)
    return jnp.minimum(jnp.sum(cdf <= u * cdf[-1]), mdp.n_states - 1).astype(jnp.int32)


def _next_from_uniform(u: jax.Array, mdp: MDP, state: jax.Array, action: jax.Array) -> jax.Array:
    cdf = jnp.cumsum(mdp.succ_p[state, action])
    k = jnp.minimum(jnp.sum(cdf <= u * cdf[-1]), cdf.shape[-1] - 1)
    return mdp.succ[state, action, k].astype(jnp.int32)


def sample_action(key: jax.Array, mdp: MDP) -> jax.Array:
    """A uniformly random valid action. Uses one uniform draw, so padding an MDP does not change the draw."""
    mdp = mdp.mdp if isinstance(mdp, BlockMDP) else mdp
    n_valid = jnp.sum(mdp.action_mask)
    a = jnp.floor(jax.random.uniform(key, dtype=jnp.float32) * n_valid).astype(jnp.int32)
    return jnp.minimum(a, n_valid - 1)


def sample_next_state(key: jax.Array, mdp: MDP, state: jax.Array, action: jax.Array) -> jax.Array:
    """Draw ``s' ~ P(. | state, action)`` by inverse CDF over the successor list (``O(K)``)."""
    return _next_from_uniform(jax.random.uniform(key, dtype=mdp.dtype), mdp, state, action)


def sample_reward(
    key: jax.Array,
    mdp: MDP,
    state: jax.Array,
    action: jax.Array,
    next_state: jax.Array,
) -> jax.Array:
    """Draw the reward of ``(state, action, next_state)``: Beta(mean*conc, (1-mean)*conc) if ``conc > 0``, else mean.

    Beta draws use :func:`jaxmdp.sampling.beta_sampling.sample_beta` (exact; several times faster than
    ``jax.random.beta`` under ``vmap``, where the reward draw dominated the cost of a step). MDPs whose static
    ``stochastic_rewards`` is False (no Beta reward anywhere, recorded at construction) compile no draw at all: the
    reward is the mean.
    """
    mean = mdp.reward_mean[state, action, next_state]
    if not mdp.stochastic_rewards:  # static: no Beta anywhere, no draw compiled
        return mean
    conc = mdp.reward_conc[state, action, next_state]
    stochastic = conc > 0
    alpha = jnp.where(stochastic, mean * conc, 1.0)
    beta = jnp.where(stochastic, (1.0 - mean) * conc, 1.0)
    draw = sample_beta(key, alpha, beta, dtype=mdp.dtype)
    return jnp.where(stochastic, draw, mean)


def reset(key: jax.Array, mdp: MDP | BlockMDP) -> tuple[jax.Array, EnvState]:
    """Start an episode: ``s0 ~ P0``, ``h = 0``. Returns ``(obs, state)``."""
    if isinstance(mdp, BlockMDP):
        _, state = reset(key, mdp.mdp)
        return observe(noise_key(key), mdp, state.state, state.h), state
    s0 = _start_from_uniform(jax.random.uniform(key, dtype=mdp.dtype), mdp)
    return s0, EnvState(state=s0, h=jnp.zeros((), jnp.int32))


def step(
    key: jax.Array, state: EnvState, action: jax.Array, mdp: MDP | BlockMDP
) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, jax.Array, dict[str, Any]]:
    """Take ``action``: returns ``(obs, state, reward, terminated, truncated, info)`` with auto-reset.

    ``info`` holds ``final_observation`` (the state reached by this action, before any reset) and ``discount``
    (0 on termination, else 1); for a BlockMDP see the module docstring.
    """
    if isinstance(mdp, BlockMDP):
        _, new_state, reward, terminated, truncated, info = step(key, state, action, mdp.mdp)
        obs = observe(noise_key(key), mdp, new_state.state, new_state.h)
        final = jnp.where(terminated, jnp.zeros_like(obs), obs)
        info = {**info, "final_observation": final, "final_state": info["final_observation"], "state": new_state.state}
        return obs, new_state, reward, terminated, truncated, info
    # One key for the reward and two uniforms for the next and reset states: fewer PRNG calls than three splits.
    k_reward, k_uniform = jax.random.split(key)
    u_next, u_reset = jax.random.uniform(k_uniform, (2,), dtype=mdp.dtype)
    action = jnp.asarray(action, jnp.int32)
    s_next = _next_from_uniform(u_next, mdp, state.state, action)
    reward = sample_reward(k_reward, mdp, state.state, action, s_next)
    h_next = state.h + 1
    terminated = (h_next >= mdp.horizon) if mdp.episodic else jnp.zeros((), bool)
    s_reset = _start_from_uniform(u_reset, mdp) if mdp.episodic else state.state
    new_state = EnvState(
        state=jnp.where(terminated, s_reset, s_next),
        h=jnp.where(terminated, 0, h_next).astype(jnp.int32),
    )
    info = {"final_observation": s_next, "discount": 1.0 - terminated.astype(mdp.dtype)}
    return new_state.state, new_state, reward, terminated, jnp.zeros((), bool), info
