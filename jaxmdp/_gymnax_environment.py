"""The gymnax ``Environment`` subclass behind :func:`jaxmdp.as_gymnax` (this module imports gymnax; see
:mod:`jaxmdp.gymnax_env` for the rules)."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from gymnax.environments import environment, spaces

from jaxmdp.blockmdp.block_mdp import BlockMDP, observe
from jaxmdp.env import EnvState, reset, step
from jaxmdp.gymnax_env import GymnaxParams, GymnaxState
from jaxmdp.mdp import MDP

__all__ = ["MDPEnvironment"]


class MDPEnvironment(environment.Environment):
    """A jaxmdp MDP or BlockMDP as a gymnax environment (made by :func:`jaxmdp.as_gymnax`).

    The MDP is the params pytree (:class:`~jaxmdp.gymnax_env.GymnaxParams`); the environment object keeps only what
    is static: the sizes, the observation kind and the MDP given to :func:`~jaxmdp.as_gymnax` for
    :attr:`default_params` and the observation bounds.
    """

    def __init__(self, mdp: MDP | BlockMDP, observation: str, max_steps_in_episode: int) -> None:
        super().__init__()
        self._mdp = mdp.strip()
        self._inner = mdp.mdp if isinstance(mdp, BlockMDP) else mdp
        self._block = isinstance(mdp, BlockMDP)
        self._observation = observation
        self._max_steps = max_steps_in_episode
        self._family = mdp.info.family
        if self._block:
            table = np.asarray(mdp.emissions)
            # Past an episode's end a BlockMDP observes all zeros (jaxmdp.observe); noise is unbounded.
            bounded = mdp.noise_kind is None
            self._obs_low = float(min(table.min(), 0.0)) if bounded else -np.inf
            self._obs_high = float(max(table.max(), 0.0)) if bounded else np.inf
            self._obs_shape = tuple(mdp.obs_shape)
            self._obs_dtype = table.dtype

    @property
    def default_params(self) -> GymnaxParams:
        return GymnaxParams(mdp=self._mdp, max_steps_in_episode=jnp.asarray(self._max_steps, jnp.int32))

    @property
    def name(self) -> str:
        """``jaxmdp-<family>`` (``jaxmdp-<family>-<emission>`` for a BlockMDP)."""
        return f"jaxmdp-{self._family}" + (f"-{self._mdp.emission_kind}" if self._block else "")

    @property
    def num_actions(self) -> int:
        return self._inner.n_actions

    def _encode(self, s: jax.Array) -> jax.Array:
        """The observation of a plain MDP's state ``s``."""
        if self._observation == "index":
            return jnp.asarray(s, jnp.int32)
        return jax.nn.one_hot(s, self._inner.n_states, dtype=jnp.float32)

    def step_env(
        self, key: jax.Array, state: GymnaxState, action: int | jax.Array, params: GymnaxParams
    ) -> tuple[jax.Array, GymnaxState, jax.Array, jax.Array, dict[str, Any]]:
        """:func:`jaxmdp.step` with ``key``, returned before its reset: the state the action reached (``h`` the
        horizon when the episode ends) and its observation; gymnax's ``step`` resets."""
        obs, new, reward, terminated, _, info = step(key, state.mdp_state, action, params.mdp)
        if self._block:
            reached, obs_reached = info["final_state"], info["final_observation"]
        else:
            reached = info["final_observation"]
            obs_reached = self._encode(reached)
        # Without termination jaxmdp.step did not reset, so its state is the one reached.
        h = jnp.where(terminated, state.mdp_state.h + 1, new.h).astype(jnp.int32)
        stepped = GymnaxState(mdp_state=EnvState(state=reached, h=h), time=state.time + 1)
        return obs_reached, stepped, reward, terminated, {"discount": info["discount"]}

    def reset_env(self, key: jax.Array, params: GymnaxParams) -> tuple[jax.Array, GymnaxState]:
        """:func:`jaxmdp.reset` with ``key``."""
        obs, mdp_state = reset(key, params.mdp)
        obs = obs if self._block else self._encode(obs)
        return obs, GymnaxState(mdp_state=mdp_state, time=jnp.zeros((), jnp.int32))

    def get_obs(self, state: GymnaxState, params: GymnaxParams | None = None, key: jax.Array | None = None) -> jax.Array:
        """The observation of ``state`` (a BlockMDP with noise needs ``key``; :func:`jaxmdp.observe`)."""
        if not self._block:
            return self._encode(state.mdp_state.state)
        params = self.default_params if params is None else params
        return observe(key, params.mdp, state.mdp_state.state, state.mdp_state.h)

    def is_terminated(self, state: GymnaxState, params: GymnaxParams) -> jax.Array:
        """Whether the episode's ``H`` actions are taken (never for a continuous MDP)."""
        if not self._inner.episodic:
            return jnp.zeros((), bool)
        return state.mdp_state.h >= params.mdp.horizon

    def action_space(self, params: GymnaxParams | None = None) -> spaces.Discrete:
        return spaces.Discrete(self._inner.n_actions)

    def observation_space(self, params: GymnaxParams | None = None) -> spaces.Space:
        """``Box(0, 1, (S,))`` (one-hot), ``Discrete(S)`` (index), or for a BlockMDP a ``Box`` of its observation
        shape bounded by the emission table's values and 0 (unbounded with noise)."""
        if self._block:
            return spaces.Box(self._obs_low, self._obs_high, self._obs_shape, self._obs_dtype)
        if self._observation == "index":
            return spaces.Discrete(self._inner.n_states)
        return spaces.Box(0.0, 1.0, (self._inner.n_states,), jnp.float32)
