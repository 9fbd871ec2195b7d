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
    "lstm_sequence",
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


# The order of flax's OptimizedLSTMCell gates in its concatenated kernels: input, forget, cell, output.
_GATES = ("i", "f", "g", "o")


def unroll(
    net: PolicyValueRNN, params: dict, carry: LSTMCarry, observations: jax.Array
) -> tuple[LSTMCarry, tuple[jax.Array, jax.Array]]:
    """The network over a sequence ``[T, *obs]`` from ``carry``: ``(final carry, (logits [T, A], values [T]))``,
    what a scan of :class:`PolicyValueRNN` step by step computes, up to rounding.

    Only the recurrence runs step by step (:func:`lstm_sequence`): the torso, the LSTM's input projection and the
    heads are matrix products over the whole sequence, and the recurrent kernel's gradient is one product
    ``H_prev^T dZ`` after the backward scan. Differentiating a scan of the cell instead accumulates a rank-one
    ``h_{t-1}^T dz_t`` into a ``[W, 4 W]`` gradient at every step of the backward pass, which XLA's CPU backend also
    computed once per gate (docs/performance.md, Deep agents).
    """
    p = params["params"]
    embedding = MLP([net.width] * net.depth, n_outputs=None, activate_final=True, batch_dims=1).apply(
        {"params": p["MLP_0"]}, observations
    )
    cell = p["OptimizedLSTMCell_0"]
    w_in = jnp.concatenate([cell[f"i{gate}"]["kernel"] for gate in _GATES], axis=-1)
    w_rec = jnp.concatenate([cell[f"h{gate}"]["kernel"] for gate in _GATES], axis=-1)
    bias = jnp.concatenate([cell[f"h{gate}"]["bias"] for gate in _GATES], axis=-1)
    carry, h = lstm_sequence(w_rec, bias, embedding @ w_in, carry)
    embedding = embedding + nn.relu(h)
    logits = nn.Dense(net.n_actions).apply({"params": p["Dense_0"]}, embedding)
    values = nn.Dense(1).apply({"params": p["Dense_1"]}, embedding)[:, 0]
    return carry, (logits, values)


def _lstm_forward(w_rec, bias, x_proj, carry):
    """The recurrence of :func:`lstm_sequence`: the last state, ``h [T, W]`` and what the backward pass reads
    besides them, ``c [T, W]``, the activated gates ``[T, 4 W]`` and ``tanh(c_t)``."""

    def step(state, x):
        c, h = state
        i, f, g, o = jnp.split(x + h @ w_rec + bias, 4, axis=-1)
        i, f, g, o = jax.nn.sigmoid(i), jax.nn.sigmoid(f), jnp.tanh(g), jax.nn.sigmoid(o)
        c_new = f * c + i * g
        tanh_c = jnp.tanh(c_new)
        h_new = o * tanh_c
        return (c_new, h_new), (h_new, c_new, jnp.concatenate([i, f, g, o], axis=-1), tanh_c)

    last, (hs, cs, gates, tanh_c) = jax.lax.scan(step, carry, x_proj)
    return last, hs, (cs, gates, tanh_c)


def _previous(first: jax.Array, seq: jax.Array) -> jax.Array:
    """``[x_0, x_1 .. x_{T-1}]`` from the start value ``x_0`` and the sequence ``[x_1 .. x_T]``."""
    return jnp.concatenate([first[None], seq[:-1]], axis=0)


@jax.custom_vjp
def lstm_sequence(
    w_rec: jax.Array, bias: jax.Array, x_proj: jax.Array, carry: LSTMCarry
) -> tuple[LSTMCarry, jax.Array]:
    """flax's ``OptimizedLSTMCell`` over a sequence whose input projections ``x_proj = x_t W_in`` (``[T, 4 W]``,
    gates ``i, f, g, o``) are given: ``z_t = x_proj_t + h_{t-1} W_rec + b``, ``i, f, o = sigmoid``, ``g = tanh``,
    ``c_t = f c_{t-1} + i g``, ``h_t = o tanh(c_t)`` (Hochreiter & Schmidhuber 1997; the paper's App. G network).
    Returns ``((c_T, h_T), h [T, W])``.

    Its gradient is back-propagation through time written out: a reverse scan carries ``(dc, dh)`` and emits each
    step's ``dz_t``; then ``dW_rec = H_prev^T dZ``, ``db = sum_t dz_t``, ``dx_proj = dZ`` (one product each).
    """
    carry, hs, _ = _lstm_forward(w_rec, bias, x_proj, carry)
    return carry, hs


def _lstm_sequence_fwd(w_rec, bias, x_proj, carry):
    last, hs, (cs, gates, tanh_c) = _lstm_forward(w_rec, bias, x_proj, carry)
    return (last, hs), (w_rec, carry, hs, cs, gates, tanh_c)


def _lstm_sequence_bwd(residuals, cotangents):
    w_rec, (c0, h0), hs, cs, gates, tanh_c = residuals
    c_prev, h_prev = _previous(c0, cs), _previous(h0, hs)
    (dc_last, dh_last), dhs = cotangents

    def back(state, x):
        dc, dh = state
        dh_out, c, gate, tc = x
        i, f, g, o = jnp.split(gate, 4, axis=-1)
        dh = dh + dh_out
        dc = dc + dh * o * (1.0 - tc * tc)
        dz = jnp.concatenate(
            [dc * g * i * (1.0 - i), dc * c * f * (1.0 - f), dc * i * (1.0 - g * g), dh * tc * o * (1.0 - o)], axis=-1
        )
        return (dc * f, dz @ w_rec.T), dz

    (dc0, dh0), dz = jax.lax.scan(back, (dc_last, dh_last), (dhs, c_prev, gates, tanh_c), reverse=True)
    return h_prev.T @ dz, jnp.sum(dz, axis=0), dz, (dc0, dh0)


lstm_sequence.defvjp(_lstm_sequence_fwd, _lstm_sequence_bwd)


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
