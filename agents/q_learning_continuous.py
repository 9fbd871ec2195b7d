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
from typing import Any

import jax
import jax.numpy as jnp

from agents.tabular_common import greedy_action_single_draw, row_max, valid_counts
from jaxmdp import dynamic_programming as dp
from jaxmdp import struct
from jaxmdp._asserts import assert_observation, assert_transition
from jaxmdp._checks import Variant, check_range
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, RunnerHints, Transition

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


# Columns of the per-(s, a) table: one gather and one scatter per update instead of four of each.
_Q, _Q_HAT, _N = range(3)


class QLearningContinuousState(struct.PyTreeNode):
    """Per-``(s, a)`` table ``[S, A, 3]`` holding the running estimate ``Q``, the optimistic ``Q_hat`` and the count
    ``N`` (as a float: exact up to ``2^24`` visits of one pair in float32), in the MDP's dtype, and the constants.
    ``V(s) = max_a Q_hat(s, a)`` is read from the table rather than stored (the same numbers: ``V(s)`` is refreshed
    exactly when ``Q_hat(s, .)`` changes)."""

    table: jax.Array
    H: jax.Array
    gamma: jax.Array
    bonus_scale: jax.Array
    min_at: jax.Array
    action_mask: jax.Array

    @property
    def Q(self) -> jax.Array:
        return self.table[..., _Q]

    @property
    def Q_hat(self) -> jax.Array:
        return self.table[..., _Q_HAT]

    @property
    def N(self) -> jax.Array:
        return self.table[..., _N].astype(jnp.int32)

    @property
    def V(self) -> jax.Array:
        return row_max(jnp.where(self.action_mask[..., None, :], self.Q_hat, -jnp.inf))


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
    dtype: Any = jnp.float32,
    *,
    variant: Variant = "paper",
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """``(H, gamma, bonus_scale, min_at')`` with ``b_tau = bonus_scale / sqrt(tau)`` (module docstring), in
    ``dtype``. ``variant="colosseum"``: the reference's exponent 0.333 and no floor on ``H``."""
    T = jnp.asarray(n_steps, dtype)
    SA = jnp.asarray(n_states, dtype) * jnp.asarray(n_actions, dtype)
    sp, delta = (jnp.asarray(x, dtype) for x in (hparams.span_approx_weight, hparams.delta))
    h_weight, min_at = (jnp.asarray(x, dtype) for x in (hparams.h_weight, hparams.min_at))
    third = _COLOSSEUM_EXPONENT if variant == "colosseum" else 1.0 / 3.0
    H = h_weight * jnp.minimum(jnp.sqrt(sp * T / SA), (T / (SA * jnp.log(4.0 * T / delta))) ** third)
    H = H if variant == "colosseum" else jnp.maximum(H, 1.0)
    bonus_scale = 4.0 * sp * jnp.sqrt(H * jnp.log(2.0 * T / delta))
    min_at = jnp.where(min_at > _MIN_AT_CUTOFF, min_at, 0.0)
    return H, 1.0 - 1.0 / H, bonus_scale, min_at


def init(
    key: jax.Array, spec: MDPSpec, hparams: QLearningContinuousHParams, variant: Variant = "paper"
) -> QLearningContinuousState:
    del key
    S, A, dtype = spec.n_states, spec.n_actions, spec.dtype
    n_s, n_a = valid_counts(spec.state_mask, spec.action_mask, dtype)
    H, gamma, bonus_scale, min_at = constants(hparams, n_s, n_a, spec.n_steps, dtype, variant=variant)
    table = jnp.stack([jnp.full((S, A), H), jnp.full((S, A), H), jnp.zeros((S, A), dtype)], axis=-1)
    return QLearningContinuousState(
        table=table,
        H=H,
        gamma=gamma,
        bonus_scale=bonus_scale,
        min_at=min_at,
        action_mask=spec.action_mask,
    )


def _stepped_table(state: QLearningContinuousState, tr: Transition, v_next: jax.Array, start: int) -> jax.Array:
    """The table after the step at ``(s, a)`` with next-state value ``v_next``: ``tau = n(s, a) + 1``,
    ``Q(s, a) <- (1 - alpha_tau) X + alpha_tau (r + gamma v_next + b_tau)`` with ``X`` the table column ``start``
    at ``(s, a)`` (``_Q`` for the paper, ``_Q_HAT`` for the reference), ``Q_hat(s, a) <- min(Q_hat(s, a), Q(s, a))``."""
    s, a = tr.obs, tr.action
    row = state.table[s, a]
    tau = row[_N] + 1.0
    alpha = jnp.maximum(state.min_at, (state.H + 1.0) / (state.H + tau))
    target = tr.reward.astype(tau.dtype) + state.gamma * v_next + state.bonus_scale / jnp.sqrt(tau)
    q = (1.0 - alpha) * row[start] + alpha * target
    return state.table.at[s, a].set(jnp.stack([q, jnp.minimum(row[_Q_HAT], q), tau]))


def update(state: QLearningContinuousState, tr: Transition) -> QLearningContinuousState:
    """One optimistic Q-learning step at ``(s, a)`` (module docstring)."""
    assert_transition(tr)
    v_next = row_max(jnp.where(state.action_mask, state.table[tr.next_obs, :, _Q_HAT], -jnp.inf))
    return state.replace(table=_stepped_table(state, tr, v_next, _Q))


def act(key: jax.Array, state: QLearningContinuousState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """Greedy in ``Q_hat(obs, .)``, exact ties at random."""
    assert_observation(obs, h)
    del h
    return greedy_action_single_draw(key, state.table[obs, :, _Q_HAT], state.action_mask)


def policy(state: QLearningContinuousState) -> jax.Array:
    """Greedy one-hot policy of ``Q_hat``, ``[S, A]`` (lowest-index ties)."""
    return dp.greedy(state.Q_hat, state.action_mask)


def greedy_actions(state: QLearningContinuousState) -> jax.Array:
    """:func:`policy` as action indices, ``[S]`` (what the runner compares and evaluates)."""
    return dp.greedy_actions(state.Q_hat, state.action_mask)


Q_LEARNING_CONTINUOUS = Agent(
    name="q_learning_continuous",
    episodic=False,
    default_hparams=QLearningContinuousHParams(),
    init=init,
    act=act,
    update=update,
    policy=policy,
    check_hparams=check_hparams,
    # Its act reads a row of the member's table, which XLA would repeat in each fusion that uses the action
    # (RunnerHints.act_apart).
    hints=RunnerHints(greedy_actions=greedy_actions, act_apart=True),
)


# ---------------------------------------------------------------------------------------------------------------
# Reference mode (docs/agents.md, "Reference mode"): the reference's update rules, as its published numbers used them
# ---------------------------------------------------------------------------------------------------------------


class QLearningContinuousColosseumState(QLearningContinuousState):
    """The reference's state: as :class:`QLearningContinuousState` plus a stored ``V[S]``, which the reference
    refreshes at the next state ``s'``, so it lags ``max_a Q_hat``.

    ``V`` cannot be read off the table (unlike the episodic reference mode's,
    :func:`agents.q_learning_episodic.table_values`): after a step at ``(s, a)`` with ``s' != s``, ``Q_hat(s, a) <- min(Q_hat(s, a), Q(s, a))``
    may lower ``Q_hat(s, a)`` while ``V(s)`` keeps ``max_a Q_hat(s, .)`` from *before* that step until ``s`` is
    next reached as a next state. That older ``Q_hat(s, a)`` is overwritten in the table (the minimum discards it,
    and the running ``Q(s, a)`` column cannot restore it without the target), so ``V(s)`` would need one stored
    number per state anyway: the stored ``V`` itself. (E.g. ``tests/test_reference_mode.py``: after the stream
    ``0 -> 1, 0 -> 1, 1 -> 0, 0 -> 0``, ``V(1) = H`` while ``max_a Q_hat(1, a) < H``.)"""

    v: jax.Array

    @property
    def V(self) -> jax.Array:
        return self.v


def init_colosseum(
    key: jax.Array, spec: MDPSpec, hparams: QLearningContinuousHParams
) -> QLearningContinuousColosseumState:
    """:func:`init` with the reference's constants and ``V = H``."""
    state = init(key, spec, hparams, variant="colosseum")
    fields = {f.name: getattr(state, f.name) for f in dataclasses.fields(state)}
    return QLearningContinuousColosseumState(**fields, v=jnp.full((spec.n_states,), state.H, state.table.dtype))


def update_colosseum(
    state: QLearningContinuousColosseumState, tr: Transition
) -> QLearningContinuousColosseumState:
    """The reference's step at ``(s, a)``: the running estimate restarts from the monotone one,
    ``Q(s, a) <- (1 - alpha_tau) Q_hat(s, a) + alpha_tau (r + gamma V(s') + b_tau)``, ``Q_hat(s, a) <- min(Q_hat(s, a),
    Q(s, a))``, and the *next* state's value is refreshed, ``V(s') <- max_a Q_hat(s', a)``."""
    assert_transition(tr)
    table = _stepped_table(state, tr, state.v[tr.next_obs], _Q_HAT)
    v_next = row_max(jnp.where(state.action_mask, table[tr.next_obs, :, _Q_HAT], -jnp.inf))
    return state.replace(table=table, v=state.v.at[tr.next_obs].set(v_next))


Q_LEARNING_CONTINUOUS_COLOSSEUM = dataclasses.replace(
    Q_LEARNING_CONTINUOUS,
    name="q_learning_continuous@colosseum",
    default_hparams=QLearningContinuousHParams(delta=0.95),
    init=init_colosseum,
    update=update_colosseum,
)
