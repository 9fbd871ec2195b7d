"""Optimistic Q-learning for average-reward MDPs (Wei, Jafarnia-Jahromi, Luo, Sharma & Jain 2020, "Model-free
reinforcement learning in infinite-horizon average-reward MDPs", Algorithm 1; paper §3.3; docs/agents.md §5).

The average-reward problem is approached through a discounted one with ``gamma = 1 - 1/H``. With the reference's
constants (``sp = span_approx_weight``, the span of the optimal bias being unknown; ``T`` the total number of steps;
``S``, ``A`` the real numbers of states and actions; ``delta`` the failure probability):

* ``H = h_weight min(sqrt(sp T / (S A)), (T / (S A ln(4 T / delta)))^(1/3))``, floored at 1 so that
  ``gamma >= 0``;
* ``alpha_tau = max(min_at', (H + 1) / (H + tau))`` with ``min_at' = min_at`` if ``min_at > 0.009`` else 0 (the
  reference's learning-rate floor; ``min_at = 0`` is the published schedule);
* bonus ``b_tau = 4 sp sqrt(H / tau ln(2 T / delta))``.

Tables start at ``Q = Q_hat = V = H`` and ``n = 0``. After ``(s, a, r, s')``: ``tau = n(s, a) <- n(s, a) + 1``,

* ``Q(s, a) <- (1 - alpha_tau) Q(s, a) + alpha_tau (r + gamma V(s') + b_tau)`` (the running estimate),
* ``Q_hat(s, a) <- min(Q_hat(s, a), Q(s, a))`` (the optimistic, monotone estimate),
* ``V(s) <- max_a Q_hat(s, a)``.

Actions are greedy in ``Q_hat(s, .)`` with exact ties at random; the policy estimate (for regret) is greedy in
``Q_hat`` with ties to the lowest index, ``[S, A]``. (docs/agents.md names the running estimate ``Q_hat`` and the
monotone one ``Q``; the names here are the paper's.)

Defaults: the benchmark's tuned ``h_weight = 0.942``, ``span_approx_weight = 0.014``, ``min_at = 0.073``
(docs/agents.md §5) and ``delta = 0.05``, the failure probability of the reference's "confidence 0.95".

Differences from the reference (Colosseum), each a return to the published algorithm:

* the running update starts from the running estimate ``Q`` (the reference restarts it from the monotone one
  every step, [quirk]);
* ``V`` is refreshed at the state just left, ``s`` (the reference refreshes the next state ``s'``, [quirk]);
* ``delta`` is the failure probability: the reference plugs its ``confidence = 0.95`` in where the failure
  probability belongs [quirk] (``delta = 0.95`` reproduces its constants);
* the exponent is exactly ``1/3`` (the reference uses 0.333); ``H`` is floored at 1 (the reference would let
  ``gamma`` go negative for tiny ``h_weight``);
* the policy estimate breaks ties towards the lowest index (the reference re-seeds 42, docs/measures.md §1.4).

``Q_LEARNING_CONTINUOUS_COLOSSEUM`` (``agents.get("q_learning_continuous", variant="colosseum")``) restores the first
four, with ``delta = 0.95`` by default (reference mode, docs/agents.md).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
from flax import struct

from agents.tabular_common import greedy_action, valid_counts
from jaxmdp import dynamic_programming as dp
from jaxmdp._checks import Variant, check_range
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, Transition

__all__ = [
    "QLearningContinuousHParams",
    "QLearningContinuousState",
    "Q_LEARNING_CONTINUOUS",
    "Q_LEARNING_CONTINUOUS_COLOSSEUM",
    "constants",
]

# Below this value the reference's learning-rate floor is switched off (docs/agents.md §5).
_MIN_AT_CUTOFF = 0.009
# The reference's approximation of the exponent 1/3 in H (reference mode).
_COLOSSEUM_EXPONENT = 0.333


class QLearningContinuousHParams(struct.PyTreeNode):
    """Hyperparameters (numeric leaves); defaults: docs/agents.md §5 cached values and ``delta = 0.05``."""

    h_weight: float | jax.Array = 0.942
    span_approx_weight: float | jax.Array = 0.014
    min_at: float | jax.Array = 0.073
    delta: float | jax.Array = 0.05


class QLearningContinuousState(struct.PyTreeNode):
    """Running estimate ``Q[S, A]``, optimistic ``Q_hat[S, A]``, ``V[S]``, counts ``N[S, A]`` and the constants."""

    Q: jax.Array
    Q_hat: jax.Array
    V: jax.Array
    N: jax.Array
    H: jax.Array
    gamma: jax.Array
    bonus_scale: jax.Array
    min_at: jax.Array
    action_mask: jax.Array


def check_hparams(hparams: QLearningContinuousHParams) -> None:
    """Domains: ``h_weight, span_approx_weight > 0``, ``0 <= min_at <= 1``, ``0 < delta < 1``."""
    check_range("h_weight", hparams.h_weight, 0.0, low_open=True)
    check_range("span_approx_weight", hparams.span_approx_weight, 0.0, low_open=True)
    check_range("min_at", hparams.min_at, 0.0, 1.0)
    check_range("delta", hparams.delta, 0.0, 1.0, low_open=True, high_open=True)


def constants(
    hparams: QLearningContinuousHParams,
    n_states: jax.Array,
    n_actions: jax.Array,
    n_steps: jax.Array,
    *,
    variant: Variant = "paper",
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """``(H, gamma, bonus_scale, min_at')`` with ``b_tau = bonus_scale / sqrt(tau)`` (module docstring).

    ``variant="colosseum"``: the reference's exponent 0.333 and no floor on ``H``."""
    T = jnp.asarray(n_steps, jnp.float32)
    SA = jnp.asarray(n_states, jnp.float32) * jnp.asarray(n_actions, jnp.float32)
    sp, delta = hparams.span_approx_weight, hparams.delta
    third = _COLOSSEUM_EXPONENT if variant == "colosseum" else 1.0 / 3.0
    H = hparams.h_weight * jnp.minimum(jnp.sqrt(sp * T / SA), (T / (SA * jnp.log(4.0 * T / delta))) ** third)
    H = H if variant == "colosseum" else jnp.maximum(H, 1.0)
    bonus_scale = 4.0 * sp * jnp.sqrt(H * jnp.log(2.0 * T / delta))
    min_at = jnp.where(hparams.min_at > _MIN_AT_CUTOFF, hparams.min_at, 0.0)
    return H, 1.0 - 1.0 / H, bonus_scale, min_at


def init(
    key: jax.Array, spec: MDPSpec, hparams: QLearningContinuousHParams, variant: Variant = "paper"
) -> QLearningContinuousState:
    del key
    S, A = spec.n_states, spec.n_actions
    hparams = jax.tree.map(lambda x: jnp.asarray(x, jnp.float32), hparams)
    n_s, n_a = valid_counts(spec.state_mask, spec.action_mask)
    H, gamma, bonus_scale, min_at = constants(hparams, n_s, n_a, spec.n_steps, variant=variant)
    Q = jnp.full((S, A), H, jnp.float32)
    return QLearningContinuousState(
        Q=Q,
        Q_hat=Q,
        V=jnp.full((S,), H, jnp.float32),
        N=jnp.zeros((S, A), jnp.int32),
        H=H,
        gamma=gamma,
        bonus_scale=bonus_scale,
        min_at=min_at,
        action_mask=spec.action_mask,
    )


def update(state: QLearningContinuousState, tr: Transition) -> QLearningContinuousState:
    """One optimistic Q-learning step at ``(s, a)`` (module docstring)."""
    s, a = tr.obs, tr.action
    tau_int = state.N[s, a] + 1
    tau = tau_int.astype(jnp.float32)
    alpha = jnp.maximum(state.min_at, (state.H + 1.0) / (state.H + tau))
    target = tr.reward + state.gamma * state.V[tr.next_obs] + state.bonus_scale / jnp.sqrt(tau)
    q = (1.0 - alpha) * state.Q[s, a] + alpha * target
    Q_hat = state.Q_hat.at[s, a].min(q)
    row = jnp.where(state.action_mask, Q_hat[s], -jnp.inf)
    return state.replace(
        Q=state.Q.at[s, a].set(q),
        Q_hat=Q_hat,
        V=state.V.at[s].set(jnp.max(row)),
        N=state.N.at[s, a].set(tau_int),
    )


def act(key: jax.Array, state: QLearningContinuousState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """Greedy in ``Q_hat(obs, .)``, exact ties at random."""
    del h
    return greedy_action(key, state.Q_hat[obs], state.action_mask)


def policy(state: QLearningContinuousState) -> jax.Array:
    """Greedy one-hot policy of ``Q_hat``, ``[S, A]`` (lowest-index ties)."""
    return dp.greedy(state.Q_hat, state.action_mask)


Q_LEARNING_CONTINUOUS = Agent(
    name="q_learning_continuous",
    episodic=False,
    default_hparams=QLearningContinuousHParams(),
    init=init,
    act=act,
    update=update,
    policy=policy,
    check_hparams=check_hparams,
)


# ---------------------------------------------------------------------------------------------------------------
# Reference mode (docs/agents.md, "Reference mode"): the reference's update rules, as its published numbers used them
# ---------------------------------------------------------------------------------------------------------------


def update_colosseum(state: QLearningContinuousState, tr: Transition) -> QLearningContinuousState:
    """The reference's step at ``(s, a)``: the running estimate restarts from the monotone one,
    ``Q(s, a) <- (1 - alpha_tau) Q_hat(s, a) + alpha_tau (r + gamma V(s') + b_tau)``, ``Q_hat(s, a) <- min(Q_hat(s, a),
    Q(s, a))``, and the *next* state's value is refreshed, ``V(s') <- max_a Q_hat(s', a)``."""
    s, a = tr.obs, tr.action
    tau_int = state.N[s, a] + 1
    tau = tau_int.astype(jnp.float32)
    alpha = jnp.maximum(state.min_at, (state.H + 1.0) / (state.H + tau))
    target = tr.reward + state.gamma * state.V[tr.next_obs] + state.bonus_scale / jnp.sqrt(tau)
    q = (1.0 - alpha) * state.Q_hat[s, a] + alpha * target
    Q_hat = state.Q_hat.at[s, a].min(q)
    row = jnp.where(state.action_mask, Q_hat[tr.next_obs], -jnp.inf)
    return state.replace(
        Q=state.Q.at[s, a].set(q),
        Q_hat=Q_hat,
        V=state.V.at[tr.next_obs].set(jnp.max(row)),
        N=state.N.at[s, a].set(tau_int),
    )


Q_LEARNING_CONTINUOUS_COLOSSEUM = dataclasses.replace(
    Q_LEARNING_CONTINUOUS,
    name="q_learning_continuous@colosseum",
    default_hparams=QLearningContinuousHParams(delta=0.95),
    init=functools.partial(init, variant="colosseum"),
    update=update_colosseum,
)
