"""Bootstrapped DQN with randomised prior functions, episodic and continuous (Osband, Blundell, Pritzel & Van Roy
2016, "Deep exploration via bootstrapped DQN"; Osband, Aslanides & Cassirer 2018, "Randomized prior functions for
deep reinforcement learning"; bsuite's TF2 baseline as wrapped by the reference, agents.md §7).

An ensemble of ``K = n_ensemble`` Q-networks, each the sum of a trainable MLP and an untrainable random prior MLP of
the same shape scaled by ``prior_scale`` (3):

    ``Q_k(o, .) = f(theta_k, o) + prior_scale * f(phi_k, o)``.

The ensemble is one network with a leading head axis on its parameters (``theta, phi: [K, ...]``), each layer one
matrix product batched over the heads (:func:`agents.deep.networks.ensemble_apply`), trained by one gradient of the
summed loss with one Adam state over the stacked parameters (one call for every head). The priors are never trained,
so their outputs on a transition's two observations are computed once, when it is stored, and read back with the
batch. Per step:

* act greedily (epsilon-greedy with ``epsilon``, 0 in the reference) in the *active* head's ``Q_k(o, .)``, exact ties
  broken uniformly at random;
* store ``(o, a, r, c, o', m, z)`` (and ``f(phi_k, o)``, ``f(phi_k, o')``) with the bootstrap mask
  ``m_k ~ Bernoulli(mask_prob)`` and the target noise ``z_k ~ N(0, 1)``, both drawn once per head per transition
  (``c`` as in DQN: 0 on an episode's last step);
* resample the active head uniformly at every episode end (episodic, as bsuite does) or with probability
  ``switch_prob`` (0.1) at every step (continuous, as the reference's wrapper does);
* every ``sgd_period`` steps once the buffer holds ``batch_size`` items (the reference's minimum), one Adam step on a
  uniform batch of ``sum_k 1/2 mean_i m_ik delta_ik^2`` with
  ``delta_ik = r_i + noise_scale z_ik + gamma c_i max_a' Q^target_k(o'_i, a') - Q_k(o_i, a_i)``; each head's
  gradient is that of its own masked loss, and Adam, elementwise, treats the heads independently. The target
  ensemble (prior included) copies the online one after every ``target_update_period``-th SGD step.

The SGD step is the agent's ``plan`` step (see :mod:`agents.deep.dqn` for why). Per-transition randomness (masks,
noise, head switches) comes from the key drawn at ``init`` folded with the step counter, since ``update`` takes no
key; same key, same run.

Policy estimate: the greedy policy of the *active* head on every row of the emission table (lowest-index ties), as
the reference evaluates it (the head that acts is the head whose regret is measured). The ensemble mean would be a
smoother estimate, but it is not the policy the agent follows: Thompson-sampling-style agents are judged on the
sample they act on, as PSRL's policy estimate is its sampled MDP's greedy policy.

Hyperparameters (:class:`BootDQNHParams`, :class:`BootDQNContinuousHParams`): traced leaves ``epsilon``,
``learning_rate``, ``discount``, ``sgd_period``, ``target_update_period``, ``mask_prob``, ``noise_scale``,
``prior_scale`` (and ``switch_prob``); static sizes ``network_width``, ``network_depth``, ``batch_size``,
``replay_capacity``, ``n_ensemble`` (one program per shape). Defaults: bsuite's (20 heads of ``[50, 50]``, batch 128,
mask 0.5, noise 0, prior scale 3, Adam 1e-3, replay 10 000, target period 4, SGD period 1) with the reference's
epsilon 0 (bsuite's own default is ``10 / (10 + t)``); discount 1 (episodic) and 0.99 (continuous).

Differences from the reference, each a return to the published algorithm:

* the reference counts ``sgd_period`` on its SGD counter, which only advances on SGD steps and starts at 1, so with
  ``sgd_period > 1`` it never trains [quirk]; here, as in DQN, the period counts environment steps;
* the reference's loss averages over heads as well, a factor ``1/K`` to which Adam is invariant up to its ``eps``.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from agents.deep import replay
from agents.deep.common import (
    DEEP_HINTS,
    assert_act,
    assert_update,
    cast_hparams,
    make_optimizer,
    observation_shape,
    observation_table,
    on_table,
)
from agents.deep.networks import ensemble_apply, mask_input_layer
from agents.deep.dqn import (
    INPUT_LAYER,
    QHParams,
    QState,
    ReplayItem,
    check_common,
    empty_item,
    epsilon_greedy,
    guarded,
    item_of,
    make_sgd_step,
    q_network,
    sgd_due,
    td_errors,
)
from jaxmdp._checks import check_int, check_range
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, Transition

__all__ = [
    "BootDQNHParams",
    "BootDQNContinuousHParams",
    "BootDQNState",
    "BootReplayItem",
    "BOOT_DQN_EPISODIC",
    "BOOT_DQN_CONTINUOUS",
    "ensemble_q",
    "head_q",
    "q_table",
]


class BootDQNHParams(QHParams):
    """BootDQN's hyperparameters (module docstring); the episodic agent's set."""

    epsilon: float | jax.Array = 0.0
    batch_size: int = struct.field(pytree_node=False, default=128)
    mask_prob: float | jax.Array = 0.5
    noise_scale: float | jax.Array = 0.0
    prior_scale: float | jax.Array = 3.0
    n_ensemble: int = struct.field(pytree_node=False, default=20)


class BootDQNContinuousHParams(BootDQNHParams):
    """The continuous agent's set: also ``switch_prob``, the per-step probability of resampling the active head."""

    discount: float | jax.Array = 0.99
    switch_prob: float | jax.Array = 0.1


class BootReplayItem(ReplayItem):
    """A stored transition with its bootstrap mask ``[K]`` (0/1), unit target noise ``[K]`` and the prior networks'
    outputs ``f(phi_k, o)`` and ``f(phi_k, o')``, ``[K, A]`` each (unscaled).

    The priors are never trained, so their outputs on a stored observation are fixed: computed once when the
    transition is stored (two observations), they spare every SGD step two of the six ensemble-wide matrix products
    per layer (the priors' forward passes on the batch; docs/performance.md, Deep agents). A batch without them
    (``None``, e.g. built by hand) has them computed from ``prior_params`` in :func:`loss`.
    """

    mask: jax.Array
    noise: jax.Array
    prior_q: jax.Array | None = None
    next_prior_q: jax.Array | None = None


class BootDQNState(QState):
    """:class:`agents.deep.dqn.QState` (parameters with a leading head axis ``K``) with the prior parameters, the
    active head and the key of the per-transition draws, as raw key data (``jax.random.key_data``: the runner hands
    the agent state back, and checkpoints it, as NumPy arrays, which typed keys cannot become)."""

    prior_params: Any
    active_head: jax.Array
    key_data: jax.Array


def ensemble_q(state: BootDQNState, params: Any, obs: jax.Array) -> jax.Array:
    """``Q_k(obs, .)`` of every head, ``[K, A]``: ``params`` (online or target, ``[K, ...]``) plus the scaled prior."""
    q = ensemble_apply(params, obs[None]) + state.hparams.prior_scale * ensemble_apply(state.prior_params, obs[None])
    return q[:, 0]


def check_hparams(hparams: BootDQNHParams) -> None:
    """DQN's domains (:func:`agents.deep.dqn.check_common`), ``n_ensemble >= 1``, ``0 < mask_prob <= 1``,
    ``noise_scale >= 0``, ``prior_scale >= 0`` and ``0 <= switch_prob <= 1``."""
    check_common(hparams)
    check_int("n_ensemble", hparams.n_ensemble, 1)
    check_range("mask_prob", hparams.mask_prob, 0.0, 1.0, low_open=True)
    check_range("noise_scale", hparams.noise_scale, 0.0)
    check_range("prior_scale", hparams.prior_scale, 0.0)
    if hasattr(hparams, "switch_prob"):
        check_range("switch_prob", hparams.switch_prob, 0.0, 1.0)


def init(key: jax.Array, spec: MDPSpec, hparams: BootDQNHParams) -> BootDQNState:
    table = observation_table(spec, "boot_dqn")
    episodic = spec.episodic
    K = hparams.n_ensemble
    net = q_network(hparams, spec.n_actions)
    obs = jnp.zeros(observation_shape(table, episodic), table.dtype)
    k_params, k_prior, k_head, k_draws = jax.random.split(key, 4)
    params = jax.vmap(lambda k: net.init(k, obs))(jax.random.split(k_params, K))
    prior = jax.vmap(lambda k: net.init(k, obs))(jax.random.split(k_prior, K))
    params, prior = (mask_input_layer(p, spec.observation_mask, INPUT_LAYER) for p in (params, prior))
    item = empty_item(table, episodic)
    zeros = jnp.zeros((K, spec.n_actions))
    item = BootReplayItem(**vars(item), mask=jnp.zeros((K,)), noise=jnp.zeros((K,)), prior_q=zeros, next_prior_q=zeros)
    buffer = replay.make(hparams.replay_capacity, hparams.batch_size)
    hparams = cast_hparams(hparams)
    return BootDQNState(
        params=params,
        prior_params=prior,
        target_params=params,
        opt_state=make_optimizer(hparams).init(params),
        replay=buffer.init(item),
        steps=jnp.zeros((), jnp.int32),
        sgd_steps=jnp.zeros((), jnp.int32),
        active_head=jax.random.randint(k_head, (), 0, K),
        key_data=jax.random.key_data(k_draws),
        observations=table,
        action_mask=spec.action_mask,
        hparams=hparams,
        n_actions=spec.n_actions,
        episodic=episodic,
    )


def head_q(state: BootDQNState, head: jax.Array, obs: jax.Array) -> jax.Array:
    """``Q_k(obs, .)`` of the one online head ``k = head``, ``[A]``."""
    net = q_network(state.hparams, state.n_actions)
    theta, phi = jax.tree.map(lambda x: x[head], (state.params, state.prior_params))
    return net.apply(theta, obs) + state.hparams.prior_scale * net.apply(phi, obs)


def act(key: jax.Array, state: BootDQNState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """Epsilon-greedy in the active head's ``Q_k(obs, .)``."""
    assert_act(state, obs, h)
    return epsilon_greedy(key, head_q(state, state.active_head, obs), state.action_mask, state.hparams.epsilon)


def update(state: BootDQNState, tr: Transition) -> BootDQNState:
    """Store the transition with fresh masks and noise and the priors' outputs on its two observations; resample the
    active head at an episode end (episodic) or with probability ``switch_prob`` (continuous)."""
    assert_update(state, tr)
    hp = state.hparams
    K = hp.n_ensemble
    key = jax.random.fold_in(jax.random.wrap_key_data(state.key_data), state.steps)
    k_mask, k_noise, k_switch, k_head = jax.random.split(key, 4)
    item = item_of(tr, state.observations, state.episodic)
    prior_q = ensemble_apply(state.prior_params, jnp.stack([item.obs, item.next_obs]))  # [K, 2, A]
    item = BootReplayItem(
        **vars(item),
        mask=jax.random.bernoulli(k_mask, hp.mask_prob, (K,)).astype(jnp.float32),
        noise=jax.random.normal(k_noise, (K,)),
        prior_q=prior_q[:, 0],
        next_prior_q=prior_q[:, 1],
    )
    switch = tr.terminated if state.episodic else jax.random.uniform(k_switch) < hp.switch_prob
    head = jnp.where(switch, jax.random.randint(k_head, (), 0, K), state.active_head)
    buffer = replay.make(hp.replay_capacity, hp.batch_size)
    return state.replace(replay=buffer.add(state.replay, item), steps=state.steps + 1, active_head=head)


def needs_plan(state: BootDQNState) -> jax.Array:
    return sgd_due(state.steps, state.replay, state.hparams, state.hparams.batch_size)


def loss(params: Any, target_params: Any, batch: BootReplayItem, state: BootDQNState) -> jax.Array:
    """``sum_k 1/2 mean_i m_ik delta_ik^2`` (module docstring), every head's layers one batched matrix product
    (:func:`agents.deep.networks.ensemble_apply`)."""
    hp = state.hparams
    if batch.prior_q is None:  # a batch built by hand: the priors' outputs from the parameters
        prior_tm1, prior_t = (ensemble_apply(state.prior_params, o) for o in (batch.obs, batch.next_obs))
    else:  # stored with the transitions (BootReplayItem): [B, K, A] -> [K, B, A]
        prior_tm1, prior_t = (jnp.swapaxes(p, 0, 1) for p in (batch.prior_q, batch.next_prior_q))
    q_tm1 = ensemble_apply(params, batch.obs) + hp.prior_scale * prior_tm1  # [K, B, A]
    q_t = ensemble_apply(target_params, batch.next_obs) + hp.prior_scale * prior_t
    target = batch.reward + hp.noise_scale * batch.noise.T  # [K, B]
    delta = jax.vmap(td_errors, (0, None, 0, None, 0, None))(
        q_tm1, batch.action, target, hp.discount * batch.continuation, q_t, state.action_mask
    )
    return 0.5 * jnp.sum(jnp.mean(batch.mask.T * delta**2, axis=1))


#: One Adam step of the ensemble loss on a uniform batch (every head at once); target copy as in DQN.
sgd_step = make_sgd_step(loss)


plan = guarded(sgd_step, needs_plan)


def q_table(state: BootDQNState, head: jax.Array | None = None) -> jax.Array:
    """Q-values of head ``head`` (default: the active head) on every row of the emission table, ``[S, A]`` or
    ``[H, S, A]``."""
    head = state.active_head if head is None else head
    return on_table(lambda o: head_q(state, head, o), state.observations, state.episodic)


def policy(state: BootDQNState) -> jax.Array:
    """Greedy one-hot policy of the active head's :func:`q_table` over the valid actions (lowest-index ties)."""
    return dp.greedy(q_table(state), state.action_mask)


def _make(episodic: bool) -> Agent:
    return Agent(
        name="boot_dqn_episodic" if episodic else "boot_dqn_continuous",
        episodic=episodic,
        default_hparams=BootDQNHParams() if episodic else BootDQNContinuousHParams(),
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


BOOT_DQN_EPISODIC = _make(True)
BOOT_DQN_CONTINUOUS = _make(False)
