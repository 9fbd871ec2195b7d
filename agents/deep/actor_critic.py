"""Feed-forward actor-critic, episodic and continuous (bsuite's ``actor_critic`` baseline; paper App. G; Williams
1992 with a TD(lambda) critic, see :mod:`agents.deep.policy_gradient`).

Network: observation -> flatten -> MLP ``[width] * depth`` (ReLU, final layer activated) -> a linear policy head
(``A`` logits, padded actions at ``-inf``) and a linear value head. Actions are sampled from ``softmax(logits)``.

Learning: ``update`` appends the step to a trajectory buffer of ``max_sequence_length`` steps (episodic: at most
``H``, an episode's length); when it is full or (episodic only) the episode ended, ``needs_plan`` turns true and
``plan`` does one Adam step of the actor-critic loss on the buffer and empties it. Learning is a ``plan`` step so
that the runner's batch-level ``lax.cond`` skips it at the steps where no member's buffer is due (inside ``plan`` a
``lax.cond`` on ``due`` keeps the post-``init`` call, and any call on a buffer not due, a no-op). The continuous
agent never sees an episode end (as the reference, whose wrapper never declares one): it learns every
``max_sequence_length`` steps and bootstraps across them.

Policy estimate (for regret): the network on every row of the noiseless emission table ``spec.observations``
(episodic: every ``(h, s)``, ``[H, S, A]``; continuous ``[S, A]``), every arg-max logit marked with 1 and the row
normalised (the reference marks ties without normalising; a policy must be a distribution here). The table is kept
in the agent state.

Hyperparameters (:class:`ActorCriticHParams`): the numeric ones are traced leaves (a grid vmaps over them); the sizes
``width``, ``depth`` and ``max_sequence_length`` shape arrays, so they are static (one compiled program per value).
Defaults: bsuite's (MLP ``[64, 64]``, sequence 32, ``lambda = 0.9``, discount 0.99 in both settings, Adam 3e-3).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
from flax import struct

from agents.deep import policy_gradient as pg
from agents.deep.common import (
    DEEP_HINTS,
    assert_act,
    assert_update,
    cast_hparams,
    make_optimizer,
    observation_shape,
    observation_table,
)
from agents.deep.networks import MLP, mask_input_layer
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, Transition

__all__ = [
    "ActorCriticHParams",
    "ActorCriticState",
    "PolicyValueNet",
    "evaluate",
    "make_agent",
    "ACTOR_CRITIC_EPISODIC",
    "ACTOR_CRITIC_CONTINUOUS",
]


class ActorCriticHParams(struct.PyTreeNode):
    """Numeric leaves: ``learning_rate`` (Adam), ``td_lambda``, ``discount`` (``gamma``), ``entropy_cost`` (weight
    of the entropy bonus; 0 in bsuite). Static sizes: ``width`` and ``depth`` of the torso, ``max_sequence_length``
    (the trajectory buffer)."""

    learning_rate: float | jax.Array = 3e-3
    td_lambda: float | jax.Array = 0.9
    discount: float | jax.Array = 0.99
    entropy_cost: float | jax.Array = 0.0
    width: int = struct.field(pytree_node=False, default=64)
    depth: int = struct.field(pytree_node=False, default=2)
    max_sequence_length: int = struct.field(pytree_node=False, default=32)


class PolicyValueNet(nn.Module):
    """``o -> (logits [A], V(o))`` for one observation: MLP torso (final ReLU), linear heads."""

    width: int
    depth: int
    n_actions: int

    @nn.compact
    def __call__(self, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        embedding = MLP([self.width] * self.depth, n_outputs=None, activate_final=True)(obs)
        return nn.Dense(self.n_actions)(embedding), nn.Dense(1)(embedding)[0]


class ActorCriticState(struct.PyTreeNode):
    """Network parameters and Adam state, the trajectory buffer, the emission table the policy estimate is read
    from, the valid actions, the hyperparameters, the number of learning steps taken, and (static) the network and
    the setting."""

    params: dict
    opt_state: tuple
    buffer: pg.Trajectory
    observations: jax.Array
    action_mask: jax.Array
    hparams: ActorCriticHParams
    n_updates: jax.Array
    net: nn.Module = struct.field(pytree_node=False)
    episodic: bool = struct.field(pytree_node=False)


def check_hparams(hparams: ActorCriticHParams) -> None:
    """See :func:`agents.deep.policy_gradient.check_common_hparams`."""
    pg.check_common_hparams(hparams)


#: Where the torso's input layer sits in the parameters of both actor-critics
#: (:func:`agents.deep.networks.mask_input_layer`).
INPUT_LAYER = ("params", "MLP_0", "Dense_0")


def initial_state(
    cls: type, key: jax.Array, spec: MDPSpec, hparams: Any, net: nn.Module, init_params: Callable, *,
    episodic: bool, name: str, **extra: Any,
) -> Any:
    """A fresh ``cls`` state: parameters ``init_params(key, observation)`` (an all-zero observation of the table's
    shape), Adam state, an empty buffer, the emission table; ``extra`` fields as given."""
    table = observation_table(spec, name, episodic)
    obs_shape = observation_shape(table, episodic)
    params = mask_input_layer(init_params(key, jnp.zeros(obs_shape, table.dtype)), spec.observation_mask, INPUT_LAYER)
    length = pg.buffer_length(hparams.max_sequence_length, spec, episodic)
    hparams = cast_hparams(hparams)
    return cls(
        params=params,
        opt_state=make_optimizer(hparams).init(params),
        buffer=pg.empty_trajectory(length, obs_shape, table.dtype),
        observations=table,
        action_mask=spec.action_mask,
        hparams=hparams,
        n_updates=jnp.zeros((), jnp.int32),
        net=net,
        episodic=episodic,
        **extra,
    )


def init(key: jax.Array, spec: MDPSpec, hparams: ActorCriticHParams, *, episodic: bool, name: str) -> ActorCriticState:
    net = PolicyValueNet(hparams.width, hparams.depth, spec.n_actions)
    return initial_state(ActorCriticState, key, spec, hparams, net, net.init, episodic=episodic, name=name)


def act(key: jax.Array, state: ActorCriticState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """``a ~ softmax(logits(obs))`` over the valid actions."""
    assert_act(state, obs, h)
    logits, _ = state.net.apply(state.params, obs)
    return pg.sample_action(key, logits, state.action_mask)


def update(state: ActorCriticState, tr: Transition) -> ActorCriticState:
    """Append the step to the buffer (learning happens in ``plan``)."""
    assert_update(state, tr)
    return state.replace(buffer=pg.append(state.buffer, tr, state.episodic))


def needs_plan(state) -> jax.Array:
    """The buffer is full or (episodic) the episode just ended."""
    return state.buffer.due


def learning_step(state, forward) -> ActorCriticState:
    """``state`` after one learning step on its buffer (:func:`agents.deep.policy_gradient.learn`) with the
    network outputs ``forward(params)`` on the buffer's observations; the buffer restarts."""
    params, opt_state = pg.learn(state.params, state.opt_state, state.buffer, forward, state.hparams, state.action_mask)
    return state.replace(
        params=params, opt_state=opt_state, buffer=pg.restart(state.buffer), n_updates=state.n_updates + 1
    )


def _learn(state: ActorCriticState) -> ActorCriticState:
    return learning_step(state, lambda p: jax.vmap(lambda o: state.net.apply(p, o))(state.buffer.observations))


def table_rows(state) -> tuple[jax.Array, tuple[int, ...]]:
    """The emission table as ``[rows, *obs]`` and the leading shape (``(S,)`` or ``(H, S)``) to restore."""
    lead = state.observations.shape[: 2 if state.episodic else 1]
    obs_shape = state.buffer.observations.shape[1:]
    return state.observations.reshape((-1, *obs_shape)), lead


def evaluate(state: ActorCriticState) -> tuple[jax.Array, jax.Array]:
    """Masked logits and values on every row of the emission table: ``[*lead, A]`` and ``[*lead]`` with ``lead``
    ``(S,)`` (continuous) or ``(H, S)`` (episodic)."""
    rows, lead = table_rows(state)
    logits, values = jax.vmap(lambda o: state.net.apply(state.params, o))(rows)
    return pg.masked_logits(logits, state.action_mask).reshape(*lead, -1), values.reshape(lead)


def _plan(learn: Callable, key: jax.Array, state):
    """One learning step on the buffer when it is due (module docstring); otherwise ``state`` unchanged."""
    del key
    return jax.lax.cond(state.buffer.due, learn, lambda s: s, state)


def _policy(evaluate: Callable, state) -> jax.Array:
    """Arg-max logits of every table row marked and normalised (module docstring)."""
    return pg.argmax_policy(evaluate(state)[0], state.action_mask)


def make_agent(
    name: str, episodic: bool, default_hparams: Any, init: Callable, act: Callable, update: Callable,
    learn: Callable, evaluate: Callable,
) -> Agent:
    """An actor-critic :class:`Agent` (``observation="emission"``): ``plan`` runs ``learn(state)`` when the buffer
    is due, ``policy`` marks the arg-max logits of ``evaluate(state)``."""
    return Agent(
        name=name,
        episodic=episodic,
        default_hparams=default_hparams,
        init=functools.partial(init, episodic=episodic, name=name),
        act=act,
        update=update,
        policy=functools.partial(_policy, evaluate),
        needs_plan=needs_plan,
        plan=functools.partial(_plan, learn),
        check_hparams=check_hparams,
        observation="emission",
        hints=DEEP_HINTS,
    )


ACTOR_CRITIC_EPISODIC = make_agent(
    "actor_critic_episodic", True, ActorCriticHParams(), init, act, update, _learn, evaluate
)
ACTOR_CRITIC_CONTINUOUS = make_agent(
    "actor_critic_continuous", False, ActorCriticHParams(), init, act, update, _learn, evaluate
)
