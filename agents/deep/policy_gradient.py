"""The pieces the two actor-critics share (bsuite's actor-critic baselines, paper App. G): a fixed-size trajectory
buffer, TD(lambda) returns, the actor-critic loss, softmax action sampling and the arg-max policy table.

Learning rule (Williams 1992, "Simple statistical gradient-following algorithms for connectionist reinforcement
learning", with a TD(lambda) critic, Sutton 1988): on a trajectory ``o_0 a_0 r_0 o_1 ... o_n`` of ``n`` steps with
per-step discounts ``g_t = discount * (1 - terminated_t)``, values ``V_t = V(o_t)`` and the lambda-returns

    ``G_{n} = V_n``,  ``G_t = r_t + g_t ((1 - lambda) V_{t+1} + lambda G_{t+1})``  (``t = n-1 .. 0``),

the loss is ``critic + actor - entropy_cost * entropy`` with

    ``critic = 1/2 mean_t (G_t - V_t)^2`` (the returns are targets: no gradient through them),
    ``actor = -mean_t log pi(a_t | o_t) sg(G_t - V_t)``,  ``entropy = mean_t H(pi(. | o_t))``.

Differences from the reference (bsuite): the losses are means over the trajectory with the critic halved (bsuite's
TF actor-critic sums the terms over time, its JAX agents take means without the 1/2); everything else is its
algorithm.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import distrax
import jax
import jax.numpy as jnp
from flax import struct

from agents.deep.common import optimizer_step
from jaxmdp._checks import check_int, check_range
from jaxmdp.experiment.agent_interface import MDPSpec, Transition

__all__ = [
    "Trajectory",
    "buffer_length",
    "empty_trajectory",
    "append",
    "lambda_returns",
    "masked_logits",
    "actor_critic_loss",
    "sample_action",
    "argmax_policy",
    "check_common_hparams",
    "restart",
    "learn",
]


class Trajectory(struct.PyTreeNode):
    """A trajectory buffer of ``L`` steps (:func:`buffer_length`), filled from the front.

    ``observations[t]`` for ``t < count`` are the observations acted on, ``observations[count]`` the last step's
    ``next_obs`` (the bootstrap observation); ``discounts[t] = 1 - terminated_t`` (the hyperparameter ``discount``
    is applied in the loss). Entries past ``count`` are stale and masked out. ``due``: a learning step must run
    (the buffer is full, or, episodic, the episode ended).
    """

    observations: jax.Array  # [L + 1, *obs]
    actions: jax.Array  # [L] int32
    rewards: jax.Array  # [L] float32
    discounts: jax.Array  # [L] float32
    count: jax.Array  # [] int32
    due: jax.Array  # [] bool

    @property
    def max_length(self) -> int:
        return self.actions.shape[0]


def buffer_length(max_sequence_length: int, spec: MDPSpec, episodic: bool) -> int:
    """The buffer's size: ``max_sequence_length``, or for an episodic agent ``min(max_sequence_length, H)`` (the
    static episode length): an episode never has more steps, so the learning steps are the same and a learning step
    does not compute the network on stale rows that can never be valid."""
    return min(max_sequence_length, spec.H) if episodic else max_sequence_length


def empty_trajectory(max_length: int, obs_shape: tuple[int, ...], obs_dtype: Any) -> Trajectory:
    """An empty buffer of ``max_length`` steps."""
    return Trajectory(
        observations=jnp.zeros((max_length + 1, *obs_shape), obs_dtype),
        actions=jnp.zeros((max_length,), jnp.int32),
        rewards=jnp.zeros((max_length,), jnp.float32),
        discounts=jnp.zeros((max_length,), jnp.float32),
        count=jnp.zeros((), jnp.int32),
        due=jnp.zeros((), bool),
    )


def append(buffer: Trajectory, tr: Transition, episodic: bool) -> Trajectory:
    """``buffer`` with ``tr`` appended; ``due`` when it is full or (``episodic`` only) ``tr`` ended the episode.

    A continuous agent never sees an episode end (the reference's wrapper never declares one): its discounts are
    all 1 and only a full buffer makes it learn.
    """
    i = buffer.count
    obs = buffer.observations.at[i].set(tr.obs.astype(buffer.observations.dtype))
    obs = obs.at[i + 1].set(tr.next_obs.astype(obs.dtype))
    ended = jnp.asarray(tr.terminated, bool) if episodic else jnp.zeros((), bool)
    count = i + 1
    return Trajectory(
        observations=obs,
        actions=buffer.actions.at[i].set(tr.action.astype(jnp.int32)),
        rewards=buffer.rewards.at[i].set(tr.reward.astype(jnp.float32)),
        discounts=buffer.discounts.at[i].set(1.0 - ended.astype(jnp.float32)),
        count=count,
        due=(count >= buffer.max_length) | ended,
    )


@jax.jit  # an eager call compiles its scan once per shape, not at every call
def lambda_returns(
    rewards: jax.Array,
    discounts: jax.Array,
    values: jax.Array,
    td_lambda: float | jax.Array,
    length: int | jax.Array | None = None,
) -> jax.Array:
    """TD(lambda) returns of a trajectory (Sutton & Barto 2018, eq. 12.18, recursive form).

    Args:
      rewards, discounts: ``[L]``; ``discounts[t]`` multiplies what follows step ``t`` (0 after a terminal).
      values: ``[L + 1]``, ``V(o_0) .. V(o_L)``.
      td_lambda: ``lambda`` in ``[0, 1]``.
      length: the number ``n <= L`` of valid steps (default ``L``); ``V(o_n)`` bootstraps the return.

    Returns:
      ``[L]``: ``G_t = r_t + d_t ((1 - lambda) V_{t+1} + lambda G_{t+1})`` for ``t < n`` with ``G_n = V_n``;
      ``G_t = V_t`` for ``t >= n``. ``lambda = 0`` gives one-step TD targets, ``lambda = 1`` the discounted
      return bootstrapped at ``o_n``.
    """
    L = rewards.shape[0]
    n = L if length is None else length
    xs = (rewards, discounts, values[1:], values[:-1], jnp.arange(L))

    def back(g_next, x):
        r, d, v_next, v, t = x
        g = jnp.where(t < n, r + d * ((1.0 - td_lambda) * v_next + td_lambda * g_next), v)
        return g, g

    return jax.lax.scan(back, values[L], xs, reverse=True)[1]


def masked_logits(logits: jax.Array, action_mask: jax.Array) -> jax.Array:
    """Logits with padded actions at ``-inf`` (probability 0)."""
    return jnp.where(action_mask, logits, -jnp.inf)


def actor_critic_loss(
    logits: jax.Array,
    values: jax.Array,
    buffer: Trajectory,
    action_mask: jax.Array,
    td_lambda: float | jax.Array,
    discount: float | jax.Array,
    entropy_cost: float | jax.Array,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """The actor-critic loss of the module docstring on the buffer's ``count`` valid steps.

    ``logits [L + 1, A]`` and ``values [L + 1]`` are the network's outputs on ``buffer.observations`` (the last
    row's logits are unused). Returns the loss and its parts (``critic``, ``actor``, ``entropy``).
    """
    L = buffer.max_length
    valid = jnp.arange(L) < buffer.count
    n = jnp.maximum(buffer.count, 1).astype(jnp.float32)
    returns = lambda_returns(
        buffer.rewards, discount * buffer.discounts, jax.lax.stop_gradient(values), td_lambda, buffer.count
    )
    advantage = returns - values[:L]
    pi = distrax.Categorical(logits=masked_logits(logits[:L], action_mask))
    critic = 0.5 * jnp.sum(jnp.where(valid, advantage**2, 0.0)) / n
    actor = -jnp.sum(jnp.where(valid, pi.log_prob(buffer.actions) * jax.lax.stop_gradient(advantage), 0.0)) / n
    entropy = jnp.sum(jnp.where(valid, pi.entropy(), 0.0)) / n
    return critic + actor - entropy_cost * entropy, {"critic": critic, "actor": actor, "entropy": entropy}


def sample_action(key: jax.Array, logits: jax.Array, action_mask: jax.Array) -> jax.Array:
    """``a ~ softmax(logits)`` over the valid actions (never a padded one; the lowest valid action if the logits
    are not finite)."""
    a = distrax.Categorical(logits=masked_logits(logits, action_mask)).sample(seed=key)
    ok = (a >= 0) & action_mask[jnp.clip(a, 0, action_mask.shape[0] - 1)]
    return jnp.where(ok, a, jnp.argmax(action_mask)).astype(jnp.int32)


def argmax_policy(logits: jax.Array, action_mask: jax.Array) -> jax.Array:
    """The reference's actor-critic policy estimate: every arg-max logit of each row marked with 1 (padded actions
    excluded), normalised so the row is a distribution (tied actions share the mass equally)."""
    z = masked_logits(logits, action_mask)
    marks = ((z == jnp.max(z, axis=-1, keepdims=True)) & action_mask).astype(jnp.float32)
    marks = jnp.where(jnp.any(marks > 0, axis=-1, keepdims=True), marks, action_mask.astype(jnp.float32))
    return marks / jnp.sum(marks, axis=-1, keepdims=True)


def check_common_hparams(hparams: Any) -> None:
    """Domains: ``learning_rate > 0``, ``td_lambda`` and ``discount`` in ``[0, 1]``, ``entropy_cost >= 0``,
    ``width``, ``depth`` and ``max_sequence_length`` integers ``>= 1``; with ``max_grad_norm`` (RNN): ``> 0``."""
    check_range("learning_rate", hparams.learning_rate, 0.0, low_open=True)
    check_range("td_lambda", hparams.td_lambda, 0.0, 1.0)
    check_range("discount", hparams.discount, 0.0, 1.0)
    check_range("entropy_cost", hparams.entropy_cost, 0.0)
    if hasattr(hparams, "max_grad_norm"):
        check_range("max_grad_norm", hparams.max_grad_norm, 0.0, low_open=True)
    for name in ("width", "depth", "max_sequence_length"):
        check_int(name, getattr(hparams, name))


def restart(buffer: Trajectory) -> Trajectory:
    """The buffer emptied (stale entries stay, masked out by ``count = 0``)."""
    return buffer.replace(count=jnp.zeros_like(buffer.count), due=jnp.zeros_like(buffer.due))


def learn(
    params: Any,
    opt_state: Any,
    buffer: Trajectory,
    forward: Callable[[Any], tuple[jax.Array, jax.Array]],
    hparams: Any,
    action_mask: jax.Array,
) -> tuple[Any, Any]:
    """One gradient step of :func:`actor_critic_loss` on ``buffer``: ``forward(params)`` gives the network's
    ``(logits [L + 1, A], values [L + 1])`` on ``buffer.observations``. Returns the new parameters and optimiser
    state."""

    def loss(p):
        logits, values = forward(p)
        return actor_critic_loss(
            logits, values, buffer, action_mask, hparams.td_lambda, hparams.discount, hparams.entropy_cost
        )[0]

    return optimizer_step(params, jax.grad(loss)(params), opt_state, hparams)
