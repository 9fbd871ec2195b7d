"""DQN, episodic and continuous (Mnih et al. 2015, "Human-level control through deep reinforcement learning";
bsuite's baseline as wrapped by the reference, agents.md §7).

A Q-network ``Q_theta(o, .)`` (:class:`agents.deep.networks.MLP`, ``[width] * depth`` ReLU layers and a linear
output of ``A`` values) reads the BlockMDP's observation ``o`` (the emission of the state). Per interaction step:

* act epsilon-greedily: with probability ``epsilon`` a uniform valid action, else ``argmax_a Q_theta(o, a)`` over the
  valid actions with exact ties broken uniformly at random;
* add ``(o, a, r, c, o')`` to a uniform replay buffer of fixed capacity (:mod:`agents.deep.replay`), where
  ``c = 0`` on the transition that ends an episode (episodic) and ``c = 1`` otherwise (a continuous MDP never
  terminates);
* every ``sgd_period`` steps, once the buffer holds ``min_replay`` items: one Adam step on a uniformly sampled batch
  of the loss ``1/2 mean_i delta_i^2`` with ``delta_i = r_i + gamma c_i max_a' Q_target(o'_i, a') - Q_theta(o_i,
  a_i)`` (the max over valid actions), and after every ``target_update_period``-th such step the target network is
  copied from the online one (it starts as a copy).

The SGD step is the agent's ``plan`` step, with ``needs_plan`` true exactly when an SGD step is due: the runner
executes ``plan`` under one ``lax.cond`` for the whole batch, so steps on which no member learns (``sgd_period > 1``,
or a buffer below ``min_replay``) cost only the acting and the buffer write. (A ``lax.cond`` inside the vmapped
``update`` would be lowered to a select and run the SGD step at every step.)

The policy estimate (for regret, agents.md §7) is the greedy action of the network on every row of the noiseless
emission table, ``[S, A]`` or ``[H, S, A]`` (one observation per in-episode step and state), one-hot, with exact
ties to the lowest action index (as the tabular agents; the reference re-seeds a generator, measures.md §1.4).

Hyperparameters (:class:`DQNHParams`): the numeric ones (``epsilon``, ``learning_rate``, ``discount``,
``sgd_period``, ``target_update_period``, ``min_replay``) are traced leaves, so one compiled program runs a grid
over them; the sizes that shape arrays (``network_width``, ``network_depth``, ``batch_size``,
``replay_capacity``) are static: hyperparameter sets that differ in them cannot share a grid (one program per
shape; :func:`agents.search_spaces.sample_candidate_groups` groups candidates accordingly). Defaults are bsuite's:
``[50, 50]``, batch 32, epsilon 0.05, target period 4, SGD period 1, Adam 1e-3, replay 10 000, min replay 100;
discount 1 (episodic) and 0.99 (continuous) as the reference's wrappers.

Differences from the bsuite TF2 code (each immaterial to the algorithm, listed for the record): the loss is the
batch mean (the spec's; the public TF2 code sums over the batch, a constant factor to which Adam is invariant up to
its ``eps``); padded actions (stacked batches) are never chosen nor maximised over.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from agents.tabular_common import greedy_action
from agents.deep import replay
from agents.deep.common import (
    DEEP_HINTS,
    assert_act,
    assert_update,
    cast_hparams,
    check_whole,
    make_optimizer,
    observation_shape,
    observation_table,
    on_table,
    optimizer_step,
)
from agents.deep.networks import MLP, mask_input_layer
from jaxmdp._checks import check_int, check_range
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, Transition

__all__ = [
    "QHParams",
    "QState",
    "DQNHParams",
    "DQNState",
    "ReplayItem",
    "DQN_EPISODIC",
    "DQN_CONTINUOUS",
    "q_network",
    "epsilon_greedy",
    "td_errors",
    "q_table",
]


class QHParams(struct.PyTreeNode):
    """The hyperparameters shared by DQN and BootDQN: numeric leaves (vmappable) and static sizes."""

    epsilon: float | jax.Array = 0.05
    learning_rate: float | jax.Array = 1e-3
    discount: float | jax.Array = 1.0
    sgd_period: int | jax.Array = 1
    target_update_period: int | jax.Array = 4
    network_width: int = struct.field(pytree_node=False, default=50)
    network_depth: int = struct.field(pytree_node=False, default=2)
    batch_size: int = struct.field(pytree_node=False, default=32)
    replay_capacity: int = struct.field(pytree_node=False, default=10_000)


class DQNHParams(QHParams):
    """DQN's hyperparameters (module docstring): :class:`QHParams` and ``min_replay``."""

    min_replay: int | jax.Array = 100


class ReplayItem(struct.PyTreeNode):
    """One stored transition ``(o, a, r, c, o')``; ``c`` is 0 where the episode ended, else 1."""

    obs: jax.Array
    action: jax.Array
    reward: jax.Array
    continuation: jax.Array
    next_obs: jax.Array


class QState(struct.PyTreeNode):
    """What DQN and BootDQN both hold: online and target parameters, Adam's state, the replay buffer, the step and
    SGD counters, the emission table (for the policy estimate) and the valid actions."""

    params: Any
    target_params: Any
    opt_state: Any
    replay: replay.ReplayState
    steps: jax.Array
    sgd_steps: jax.Array
    observations: jax.Array
    action_mask: jax.Array
    hparams: Any
    n_actions: int = struct.field(pytree_node=False)
    episodic: bool = struct.field(pytree_node=False)


class DQNState(QState):
    """DQN's state (:class:`QState` with :class:`DQNHParams`)."""


#: Where the Q-network's input layer sits in its parameters (:func:`agents.deep.networks.mask_input_layer`).
INPUT_LAYER = ("params", "Dense_0")


def q_network(hparams: Any, n_actions: int) -> MLP:
    """The Q-network: ``[network_width] * network_depth`` ReLU layers, then ``n_actions`` linear outputs."""
    return MLP(hidden=(hparams.network_width,) * hparams.network_depth, n_outputs=n_actions)


def epsilon_greedy(
    key: jax.Array, q: jax.Array, action_mask: jax.Array, epsilon: jax.Array
) -> jax.Array:
    """With probability ``epsilon`` a uniform valid action, else greedy in ``q`` (exact ties uniformly at random).

    The uniform action is the random tie-break among all valid actions (``q`` all zero). Both tie-breaks run as one
    call vmapped over their two keys: the same numbers as two calls, in one random-bits computation (on CPU each is a
    loop of its own, and the acting step pays a few of them per interaction step).
    """
    k_explore, k_uniform, k_greedy = jax.random.split(key, 3)
    uniform, greedy = jax.vmap(greedy_action, in_axes=(0, 0, None))(
        jnp.stack([k_uniform, k_greedy]), jnp.stack([jnp.zeros_like(q), q]), action_mask
    )
    return jnp.where(jax.random.uniform(k_explore) < epsilon, uniform, greedy)


def td_errors(
    q_tm1: jax.Array,
    action: jax.Array,
    target: jax.Array,
    discount: jax.Array,
    q_t: jax.Array,
    action_mask: jax.Array,
) -> jax.Array:
    """Q-learning TD errors of a batch, ``target_i + discount_i max_{a' valid} q_t[i, a'] - q_tm1[i, action_i]``
    (``target_i`` is the reward, plus the target noise for BootDQN); ``q_*`` are ``[B, A]``."""
    v_t = jnp.max(jnp.where(action_mask, q_t, -jnp.inf), axis=-1)
    q_a = jnp.take_along_axis(q_tm1, action[:, None], axis=-1)[:, 0]
    return target + discount * jax.lax.stop_gradient(v_t) - q_a


def _check_sizes(hparams: Any) -> None:
    check_int("network_width", hparams.network_width, 1)
    check_int("network_depth", hparams.network_depth, 1)
    check_int("batch_size", hparams.batch_size, 1)
    check_int("replay_capacity", hparams.replay_capacity, hparams.batch_size)


def check_common(hparams: Any) -> None:
    """The domains shared by DQN and BootDQN: sizes are integers >= 1 with ``replay_capacity >= batch_size``;
    ``0 <= epsilon <= 1``, ``learning_rate > 0``, ``0 <= discount <= 1``, whole ``sgd_period`` and
    ``target_update_period >= 1``."""
    _check_sizes(hparams)
    check_range("epsilon", hparams.epsilon, 0.0, 1.0)
    check_range("learning_rate", hparams.learning_rate, 0.0, low_open=True)
    check_range("discount", hparams.discount, 0.0, 1.0)
    check_whole("sgd_period", hparams.sgd_period, 1)
    check_whole("target_update_period", hparams.target_update_period, 1)


def check_hparams(hparams: DQNHParams) -> None:
    """:func:`check_common`, and a whole ``min_replay`` in ``[1, replay_capacity]`` (else it never learns)."""
    check_common(hparams)
    check_whole("min_replay", hparams.min_replay, 1, hparams.replay_capacity)


def empty_item(table: jax.Array, episodic: bool) -> ReplayItem:
    """A zero transition that fixes the buffer's shapes and dtypes."""
    obs = jnp.zeros(observation_shape(table, episodic), table.dtype)
    return ReplayItem(obs, jnp.zeros((), jnp.int32), jnp.zeros(()), jnp.zeros(()), obs)


def item_of(tr: Transition, table: jax.Array, episodic: bool) -> ReplayItem:
    """The stored form of a transition (``continuation = 0`` on an episode's last step when episodic)."""
    continuation = 1.0 - tr.terminated.astype(jnp.float32) if episodic else jnp.ones(())
    return ReplayItem(
        obs=jnp.asarray(tr.obs, table.dtype),
        action=jnp.asarray(tr.action, jnp.int32),
        reward=jnp.asarray(tr.reward, jnp.float32),
        continuation=continuation,
        next_obs=jnp.asarray(tr.next_obs, table.dtype),
    )


def init(key: jax.Array, spec: MDPSpec, hparams: DQNHParams) -> DQNState:
    table = observation_table(spec, "dqn")
    episodic = spec.episodic
    net = q_network(hparams, spec.n_actions)
    params = net.init(key, jnp.zeros(observation_shape(table, episodic), table.dtype))
    params = mask_input_layer(params, spec.observation_mask, INPUT_LAYER)
    buffer = replay.make(hparams.replay_capacity, hparams.batch_size)
    hparams = cast_hparams(hparams)
    return DQNState(
        params=params,
        target_params=params,
        opt_state=make_optimizer(hparams).init(params),
        replay=buffer.init(empty_item(table, episodic)),
        steps=jnp.zeros((), jnp.int32),
        sgd_steps=jnp.zeros((), jnp.int32),
        observations=table,
        action_mask=spec.action_mask,
        hparams=hparams,
        n_actions=spec.n_actions,
        episodic=episodic,
    )


def act(key: jax.Array, state: DQNState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """Epsilon-greedy in ``Q_theta(obs, .)`` (the observation carries whatever time information the emission has)."""
    assert_act(state, obs, h)
    q = q_network(state.hparams, state.n_actions).apply(state.params, obs)
    return epsilon_greedy(key, q, state.action_mask, state.hparams.epsilon)


def update(state: DQNState, tr: Transition) -> DQNState:
    """Store the transition; learning happens in :func:`plan` when :func:`needs_plan` says an SGD step is due."""
    assert_update(state, tr)
    buffer = replay.make(state.hparams.replay_capacity, state.hparams.batch_size)
    item = item_of(tr, state.observations, state.episodic)
    return state.replace(replay=buffer.add(state.replay, item), steps=state.steps + 1)


def sgd_due(steps: jax.Array, replay_state: replay.ReplayState, hparams: Any, min_replay: Any) -> jax.Array:
    """An SGD step is due after step ``steps`` (1-based) if ``steps`` is a multiple of ``sgd_period`` and the buffer
    holds at least ``min_replay`` items."""
    return (steps % hparams.sgd_period == 0) & (replay.size(replay_state) >= min_replay)


def needs_plan(state: DQNState) -> jax.Array:
    return sgd_due(state.steps, state.replay, state.hparams, state.hparams.min_replay)


def loss(params: Any, target_params: Any, batch: ReplayItem, state: DQNState) -> jax.Array:
    """``1/2 mean_i delta_i^2`` over the batch (module docstring)."""
    net = q_network(state.hparams, state.n_actions)
    q_tm1 = jax.vmap(lambda o: net.apply(params, o))(batch.obs)
    q_t = jax.vmap(lambda o: net.apply(target_params, o))(batch.next_obs)
    delta = td_errors(
        q_tm1, batch.action, batch.reward, state.hparams.discount * batch.continuation, q_t, state.action_mask
    )
    return 0.5 * jnp.mean(delta**2)


def guarded(sgd: Callable[[jax.Array, Any], Any], due: Callable[[Any], jax.Array]) -> Callable[[jax.Array, Any], Any]:
    """``plan``: ``sgd`` when ``due(state)``, else the state unchanged. The guard matters where ``plan`` is called
    unconditionally (once after ``init``); in the step loop the runner already calls it only when due."""
    return lambda key, state: jax.lax.cond(due(state), sgd, lambda k, s: s, key, state)


def make_sgd_step(loss_fn: Callable[[Any, Any, Any, Any], jax.Array]) -> Callable[[jax.Array, Any], Any]:
    """``sgd_step(key, state)``: one Adam step of ``loss_fn(params, target_params, batch, state)`` on a uniform batch
    from the replay buffer; the target copies the online network after every ``target_update_period``-th step."""

    def sgd_step(key: jax.Array, state: QState) -> QState:
        hp = state.hparams
        batch = replay.make(hp.replay_capacity, hp.batch_size).sample(state.replay, key).experience
        grads = jax.grad(loss_fn)(state.params, state.target_params, batch, state)
        params, opt_state = optimizer_step(state.params, grads, state.opt_state, hp)
        sgd_steps = state.sgd_steps + 1
        copy = sgd_steps % hp.target_update_period == 0
        target = jax.tree.map(lambda p, t: jnp.where(copy, p, t), params, state.target_params)
        return state.replace(params=params, target_params=target, opt_state=opt_state, sgd_steps=sgd_steps)

    return sgd_step


sgd_step = make_sgd_step(loss)
plan = guarded(sgd_step, needs_plan)


def q_table(state: DQNState) -> jax.Array:
    """The network's Q-values on every row of the emission table, ``[S, A]`` or ``[H, S, A]``."""
    net = q_network(state.hparams, state.n_actions)
    return on_table(lambda o: net.apply(state.params, o), state.observations, state.episodic)


def policy(state: DQNState) -> jax.Array:
    """Greedy one-hot policy of :func:`q_table` over the valid actions (lowest-index ties)."""
    return dp.greedy(q_table(state), state.action_mask)


def _make(episodic: bool) -> Agent:
    return Agent(
        name="dqn_episodic" if episodic else "dqn_continuous",
        episodic=episodic,
        default_hparams=DQNHParams(discount=1.0 if episodic else 0.99),
        init=init,
        act=act,
        update=update,
        policy=policy,
        needs_plan=needs_plan,
        plan=plan,
        check_hparams=check_hparams,
        observation="emission",
        hints=DEEP_HINTS,
    )


DQN_EPISODIC = _make(True)
DQN_CONTINUOUS = _make(False)
