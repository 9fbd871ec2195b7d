"""A gymnax environment of an MDP or BlockMDP: :func:`as_gymnax`.

``env, params = jaxmdp.as_gymnax(mdp)`` gives a subclass of gymnax's ``Environment`` (gymnax >= 1.0) whose params
pytree (:class:`GymnaxParams`) holds the MDP, so that one compiled ``env.step`` vmaps over a stacked batch of MDPs of
one shape, and whose state (:class:`GymnaxState`) is jaxmdp's :class:`~jaxmdp.EnvState` plus gymnax's step counter
``time``. Transitions and rewards are :func:`jaxmdp.step`'s: ``env.step_env(key, ...)`` is ``jaxmdp.step(key, ...)``
seen before its own reset, and ``env.reset_env(key, ...)`` is ``jaxmdp.reset(key, ...)``. gymnax's ``env.step``
splits its key into a step key and a reset key and resets by itself when the episode is done (terminated or
truncated), as for every gymnax environment.

Observations: for an MDP the one-hot vector of the state (``float32``, ``observation="one_hot"``, the default) or its
index (``observation="index"``); for a BlockMDP its emission (the observation :func:`jaxmdp.step` returns).

Episodes: an episodic MDP terminates after ``H`` actions (``terminated`` True, ``info["discount"]`` 0, the state
reached and its observation in ``info["final_observation"]``; a BlockMDP's is all zeros past the episode's end, as in
:func:`jaxmdp.observe`). A continuous MDP never terminates; ``max_steps_in_episode`` (default: never) truncates an
episode after that many steps, for either kind (``truncated`` True, then a reset from ``P0``).

gymnax is an optional dependency: this module imports without it and :func:`as_gymnax` raises ``ImportError`` naming
the extra to install.
"""

from __future__ import annotations

import importlib
import importlib.metadata
from typing import Any

import jax

from jaxmdp import struct
from jaxmdp._checks import check_int, did_you_mean
from jaxmdp.blockmdp.block_mdp import BlockMDP
from jaxmdp.env import EnvState
from jaxmdp.mdp import MDP

__all__ = ["as_gymnax", "GymnaxParams", "GymnaxState", "OBSERVATIONS", "NEVER"]

#: The observations of a plain MDP: its state's one-hot vector (float32) or its index (int32).
OBSERVATIONS = ("one_hot", "index")
#: ``max_steps_in_episode`` that never truncates: gymnax's step counter is an int32.
NEVER = 2**31 - 1


@struct.dataclass
class GymnaxParams:
    """The params of the gymnax environment: the MDP (or BlockMDP) and gymnax's time limit.

    A stacked batch (:func:`jaxmdp.stack`) in ``mdp`` vmaps ``env.step`` over MDPs: ``jax.vmap(env.step,
    in_axes=(0, 0, 0, GymnaxParams(mdp=0, max_steps_in_episode=None)))``.
    """

    mdp: MDP | BlockMDP
    max_steps_in_episode: jax.Array


@struct.dataclass
class GymnaxState:
    """The environment state: jaxmdp's state (index and in-episode step ``h``) and gymnax's steps since the reset."""

    mdp_state: EnvState
    time: jax.Array


def _distribution_name() -> str:
    """The distribution that installs the ``jaxmdp`` package (for the install hint)."""
    try:
        names = importlib.metadata.packages_distributions().get("jaxmdp")
    except Exception:  # pragma: no cover - metadata unavailable (e.g. a source tree on sys.path)
        names = None
    return names[0] if names else "jaxmdp"


def _require_gymnax() -> None:
    try:
        importlib.import_module("gymnax.environments.environment")
    except ImportError as err:
        raise ImportError(
            f'jaxmdp.as_gymnax needs gymnax, an optional dependency: pip install "{_distribution_name()}[gymnax]"'
        ) from err


def as_gymnax(
    mdp: MDP | BlockMDP, observation: str | None = None, max_steps_in_episode: int | None = None
) -> tuple[Any, GymnaxParams]:
    """The gymnax environment of ``mdp`` and its default params: ``env, params = as_gymnax(mdp)``.

    ``env`` subclasses ``gymnax.environments.environment.Environment``: ``env.reset(key, params) -> (obs, state)``
    and ``env.step(key, state, action, params) -> (obs, state, reward, terminated, truncated, info)`` with gymnax's
    auto-reset, ``env.action_space(params)`` (``Discrete(A)``), ``env.observation_space(params)``,
    ``env.default_params``, ``env.name`` and ``env.num_actions``; gymnax's wrappers apply to it. See the module
    docstring for the observations and episodes.

    Args:
      mdp: one MDP (:func:`jaxmdp.make`, :func:`jaxmdp.custom_mdp`), episodic or continuous, or one BlockMDP
        (:func:`jaxmdp.block_mdp`). To vmap over several MDPs of one shape, pass one of them here and a
        :class:`GymnaxParams` of their stack to ``env.step``.
      observation: for an MDP ``"one_hot"`` (default: ``float32`` vector of length ``S``) or ``"index"`` (the
        ``int32`` state); for a BlockMDP ``"emission"`` (the default and only choice).
      max_steps_in_episode: gymnax's time limit, an integer >= 1: an episode still running after that many steps
        is truncated. Default: never (:data:`NEVER`), so episodic MDPs end at their horizon and continuous MDPs run
        on.

    Raises:
      ImportError: gymnax is not installed (the message names the extra).
      TypeError: ``mdp`` is neither an MDP nor a BlockMDP.
      ValueError: ``mdp`` is a stacked batch; ``observation`` or ``max_steps_in_episode`` is not allowed.
    """
    if not isinstance(mdp, (MDP, BlockMDP)):
        raise TypeError(f"mdp must be a jaxmdp.MDP or jaxmdp.BlockMDP; got {type(mdp).__name__}")
    inner = mdp.mdp if isinstance(mdp, BlockMDP) else mdp
    if inner.T.ndim != 3:
        raise ValueError(
            f"mdp must be one MDP (T of shape [S, A, S]); got a stacked batch with T of shape {inner.T.shape}: pass "
            "one member and vmap env.step over a GymnaxParams of the stack"
        )
    allowed = ("emission",) if isinstance(mdp, BlockMDP) else OBSERVATIONS
    observation = allowed[0] if observation is None else observation
    if observation not in allowed:
        kind = "a BlockMDP" if isinstance(mdp, BlockMDP) else "an MDP"
        raise ValueError(
            f"observation must be one of {list(allowed)} for {kind}; got {observation!r}{did_you_mean(observation, allowed)}"
        )
    limit = NEVER if max_steps_in_episode is None else check_int(
        "max_steps_in_episode", max_steps_in_episode, 1, NEVER
    )
    _require_gymnax()
    from jaxmdp._gymnax_environment import MDPEnvironment

    env = MDPEnvironment(mdp, observation, limit)
    return env, env.default_params


def __getattr__(name: str) -> Any:
    # The Environment subclass needs gymnax at class creation, so it lives in its own module, imported on access.
    if name == "MDPEnvironment":
        _require_gymnax()
        from jaxmdp._gymnax_environment import MDPEnvironment

        return MDPEnvironment
    raise AttributeError(f"module 'jaxmdp.gymnax_env' has no attribute {name!r}")
