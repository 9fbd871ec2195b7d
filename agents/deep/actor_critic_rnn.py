"""Recurrent actor-critic, episodic and continuous (bsuite's ``actor_critic_rnn`` baseline; paper App. G; the
learning rule of :mod:`agents.deep.policy_gradient` with an LSTM, Hochreiter & Schmidhuber 1997).

Network, per step: observation -> flatten -> MLP ``[width] * depth`` (ReLU, final layer activated) = ``e`` ->
LSTM(``width``; recurrent kernels orthogonal at init, :func:`agents.deep.networks.orthogonal`) with output ``y`` ->
skip connection ``e + ReLU(y)`` -> linear policy logits (padded actions at ``-inf``) and linear value. Actions are
sampled from ``softmax(logits)``.

Recurrent state: the acting LSTM state ``carry`` lives in the agent state. ``act`` cannot change the state (the
protocol), so ``update`` advances ``carry`` through the step's observation with the same parameters ``act`` used
(the same computation, one more forward pass per step); after a step that ends the episode (episodic only) it is
reset to zero, so each episode starts from a fresh state. ``start_carry`` is the acting state at the first step of
the buffered sequence: the learning step replays the whole sequence (and the bootstrap observation) through the LSTM
from it, and the gradient flows through the unrolled sequence (back-propagation through time within the sequence;
``start_carry`` itself is data). After learning, ``start_carry`` becomes the current acting state, the one the next
sequence starts from.

Learning, buffer and its timing are those of :mod:`agents.deep.actor_critic`, with the gradient clipped to global
norm ``max_grad_norm`` before Adam and an entropy bonus of weight ``entropy_cost`` (bsuite: 5 and 0).

Policy estimate: the network on every row of the emission table from a zero (fresh) LSTM state, i.e. the policy
at the first step of an episode for every observation; arg-max logits marked with 1 and normalised. (A recurrent
policy has no per-state policy; the fresh state is the only one that does not depend on a history.)

Differences from the reference (bsuite): the sequence start state is the acting state at the sequence's first
step; bsuite keeps the state after it has also fed the bootstrap observation through the LSTM, so each later
sequence's replay starts one observation off from the states the agent acted with ([quirk]). The reference's
episodic wrapper replaces an out-of-range sampled action by a uniform one; here padded actions have probability 0.
"""

from __future__ import annotations

import flax.linen as nn
import jax
import jax.numpy as jnp

from agents.deep import policy_gradient as pg
from agents.deep.actor_critic import (
    ActorCriticHParams,
    ActorCriticState,
    initial_state,
    learning_step,
    make_agent,
    table_rows,
)
from agents.deep.common import assert_act, assert_update
from agents.deep.networks import MLP, orthogonal
from jaxmdp.experiment.agent_interface import MDPSpec, Transition

__all__ = [
    "ActorCriticRNNHParams",
    "ActorCriticRNNState",
    "PolicyValueRNN",
    "unroll",
    "evaluate",
    "ACTOR_CRITIC_RNN_EPISODIC",
    "ACTOR_CRITIC_RNN_CONTINUOUS",
]


class ActorCriticRNNHParams(ActorCriticHParams):
    """Those of :class:`~agents.deep.actor_critic.ActorCriticHParams` plus ``max_grad_norm`` (a leaf: the
    global-norm gradient clip)."""

    max_grad_norm: float | jax.Array = 5.0


LSTMCarry = tuple[jax.Array, jax.Array]


class PolicyValueRNN(nn.Module):
    """``(carry, o) -> (carry', (logits [A], V))`` for one observation (module docstring)."""

    width: int
    depth: int
    n_actions: int

    @nn.compact
    def __call__(self, carry: LSTMCarry, obs: jax.Array) -> tuple[LSTMCarry, tuple[jax.Array, jax.Array]]:
        embedding = MLP([self.width] * self.depth, n_outputs=None, activate_final=True)(obs)
        # flax's default recurrent-kernel initialiser, drawn one key at a time under vmap (no jaxlib 0.10.2 deadlock).
        carry, y = nn.OptimizedLSTMCell(self.width, recurrent_kernel_init=orthogonal())(carry, embedding)
        embedding = embedding + nn.relu(y)
        return carry, (nn.Dense(self.n_actions)(embedding), nn.Dense(1)(embedding)[0])


class ActorCriticRNNState(ActorCriticState):
    """That of :class:`~agents.deep.actor_critic.ActorCriticState` plus the acting LSTM state ``carry`` and the
    sequence start state ``start_carry`` (module docstring)."""

    carry: LSTMCarry
    start_carry: LSTMCarry


def zero_carry(width: int) -> LSTMCarry:
    """The fresh LSTM state ``(c, h) = (0, 0)``."""
    return jnp.zeros((width,), jnp.float32), jnp.zeros((width,), jnp.float32)


def unroll(net: PolicyValueRNN, params: dict, carry: LSTMCarry, observations: jax.Array):
    """The network over a sequence ``[T, *obs]`` from ``carry``: ``(final carry, (logits [T, A], values [T]))``."""
    return jax.lax.scan(lambda c, o: net.apply(params, c, o), carry, observations)


def init(
    key: jax.Array, spec: MDPSpec, hparams: ActorCriticRNNHParams, *, episodic: bool, name: str
) -> ActorCriticRNNState:
    net = PolicyValueRNN(hparams.width, hparams.depth, spec.n_actions)
    carry = zero_carry(hparams.width)
    return initial_state(
        ActorCriticRNNState, key, spec, hparams, net, lambda k, o: net.init(k, carry, o),
        episodic=episodic, name=name, carry=carry, start_carry=carry,
    )


def act(key: jax.Array, state: ActorCriticRNNState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """``a ~ softmax(logits(carry, obs))`` over the valid actions."""
    assert_act(state, obs, h)
    _, (logits, _) = state.net.apply(state.params, state.carry, obs)
    return pg.sample_action(key, logits, state.action_mask)


def update(state: ActorCriticRNNState, tr: Transition) -> ActorCriticRNNState:
    """Advance the acting LSTM state through ``tr.obs`` (reset to zero after an episode's last step, episodic) and
    append the step to the buffer."""
    assert_update(state, tr)
    carry, _ = state.net.apply(state.params, state.carry, tr.obs)
    if state.episodic:
        carry = jax.tree.map(lambda c: jnp.where(tr.terminated, jnp.zeros_like(c), c), carry)
    return state.replace(carry=carry, buffer=pg.append(state.buffer, tr, state.episodic))


def _learn(state: ActorCriticRNNState) -> ActorCriticRNNState:
    forward = lambda p: unroll(state.net, p, state.start_carry, state.buffer.observations)[1]  # noqa: E731
    return learning_step(state, forward).replace(start_carry=state.carry)


def evaluate(state: ActorCriticRNNState) -> tuple[jax.Array, jax.Array]:
    """Masked logits and values on every row of the emission table from a zero LSTM state: ``[*lead, A]`` and
    ``[*lead]`` with ``lead`` ``(S,)`` or ``(H, S)``."""
    rows, lead = table_rows(state)
    fresh = zero_carry(state.net.width)
    _, (logits, values) = jax.vmap(lambda o: state.net.apply(state.params, fresh, o))(rows)
    return pg.masked_logits(logits, state.action_mask).reshape(*lead, -1), values.reshape(lead)


ACTOR_CRITIC_RNN_EPISODIC = make_agent(
    "actor_critic_rnn_episodic", True, ActorCriticRNNHParams(), init, act, update, _learn, evaluate
)
ACTOR_CRITIC_RNN_CONTINUOUS = make_agent(
    "actor_critic_rnn_continuous", False, ActorCriticRNNHParams(), init, act, update, _learn, evaluate
)
