"""Q-learning with UCB-Hoeffding or UCB-Bernstein bonuses, episodic (Jin, Allen-Zhu, Bubeck & Jordan 2018, "Is
Q-learning provably efficient?", Algorithms 1 and 2; paper §3.3; docs/agents.md §2).

Tables ``Q_h(s, a)``, ``V_h(s)`` and counts ``N_h(s, a)`` for ``h = 0 .. H-1`` (``V_H = 0``), initialised
optimistically to ``Q = V = H`` and ``N = 0``; ``iota = ln(S A T / p)`` with ``T`` the total number of steps. After
the step ``(s, a, r, s')`` taken at in-episode step ``h``:

* ``t = N_h(s, a) <- N_h(s, a) + 1`` and ``alpha_t = max(min_at, (H + 1) / (H + t))``;
* Hoeffding bonus ``b_t = c_1 sqrt(H^3 iota / t)``;
* Bernstein bonus: with ``W_t`` the empirical variance of the next-state values ``V_{h+1}(s')`` seen at this
  ``(h, s, a)`` (running sums of ``V`` and ``V^2``),
  ``beta_t = min(c_1 (sqrt(H / t (W_t + H) iota) + sqrt(H^7 S A) iota / t), c_2 sqrt(H^3 iota / t))`` and
  ``b_t = (beta_t - (1 - alpha_t) beta_{t-1}) / (2 alpha_t)`` (``beta_0 = 0``);
* ``Q_h(s, a) <- (1 - alpha_t) Q_h(s, a) + alpha_t (r + V_{h+1}(s') + b_t)`` and
  ``V_h(s) <- min(H, max_a Q_h(s, a))``.

The last step of an episode reads ``V_H = 0``. Actions are greedy in ``Q_h(s, .)`` with exact ties broken at random
(one uniform draw per step, :func:`~agents.tabular_common.greedy_action_single_draw`);
the policy estimate (for regret) is greedy in ``Q`` with ties to the lowest action index, ``[H, S, A]``. ``S`` and
``A`` count the real (unpadded) states and actions; ``H`` is the member's own horizon.

Hyperparameters: ``c_1``, ``c_2``, ``min_at``, ``p`` and ``bernstein`` (1: Bernstein, 0: Hoeffding); the defaults are
the benchmark's tuned values (docs/agents.md §2). ``min_at`` floors the learning rate as in the reference; ``min_at =
0`` gives Jin et al.'s schedule exactly.

Differences from the reference (Colosseum), each a return to the published algorithm:

* counts start at 0, so the first visit has ``t = 1`` and ``alpha_1 = 1`` (the reference starts at 1, [quirk]);
* the update weighs the old value by ``1 - alpha_t`` and the target by ``alpha_t`` (the reference swaps them,
  [quirk]);
* the Bernstein variance term is ``H / t (W_t + H)`` with ``W_t`` the empirical variance (the reference uses
  ``H (sum V^2 - sum V)^2 / t^2 + H``, [quirk]);
* ``V`` starts at ``H`` (optimistic, as ``max_a Q`` of the initial table), not 0;
* the policy estimate breaks ties towards the lowest index (the reference re-seeds 42, docs/measures.md §1.4).

``Q_LEARNING_EPISODIC_COLOSSEUM`` (``agents.get("q_learning_episodic", variant="colosseum")``) restores the first four
(reference mode, docs/agents.md).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from agents.tabular_common import greedy_action_single_draw, read_at, row_max, valid_counts, write_at
from jaxmdp import dynamic_programming as dp
from jaxmdp import struct
from jaxmdp._asserts import assert_observation, assert_transition
from jaxmdp._checks import Variant, check_range
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, RunnerHints, Transition

__all__ = ["QLearningEpisodicHParams", "QLearningEpisodicState", "Q_LEARNING_EPISODIC", "Q_LEARNING_EPISODIC_COLOSSEUM"]


class QLearningEpisodicHParams(struct.PyTreeNode):
    """Hyperparameters (numeric leaves, so a grid can vmap over them); defaults: docs/agents.md §2, cached values."""

    c_1: float | jax.Array = 0.9415278732894797
    c_2: float | jax.Array = 0.013873778519317169
    min_at: float | jax.Array = 0.07263563483119442
    p: float | jax.Array = 0.05
    bernstein: bool | jax.Array = True


# Columns of the per-(h, s, a) statistics table: one gather and one scatter per update instead of four. ``Q`` has an
# array of its own: acting, the next state's value and the greedy policy read only ``Q``, and a dense ``[H, S, A]``
# table is a fifth of the memory they would otherwise stride through (the policy is extracted for every member at
# every log).
_N, _SUM_V, _SUM_V2, _BETA = range(4)


def table_values(
    q: jax.Array, stats: jax.Array, action_mask: jax.Array, horizon: jax.Array, variant: Variant = "paper"
) -> jax.Array:
    """``V_h(s) = min(H, max_a Q_h(s, a))`` from rows ``q[..., A]`` and their statistics ``stats[..., A, 4]``.

    ``variant="colosseum"``: the reference's ``V``, which starts at 0 (``Q`` at ``H``) and is set to
    ``min(H, max_a Q_h(s, a))`` after every update at ``(h, s)``. ``Q_h(s, .)`` changes only in those updates, so
    ``V_h(s)`` is that value from the first update at ``(h, s)`` on and 0 before it; the reference's counts start
    at 1 and only updates raise them, so "updated" is ``max_a N_h(s, a) > 1``. (The paper's ``V`` starts at
    ``H = max_a Q`` of the initial table, so it needs no such test.) Rows from the horizon on are the caller's.
    """
    v = jnp.minimum(horizon, row_max(jnp.where(action_mask, q, -jnp.inf)))
    if variant == "colosseum":
        v = jnp.where(row_max(stats[..., _N]) > 1.0, v, 0.0)
    return v


class QLearningEpisodicState(struct.PyTreeNode):
    """``q[H, S, A]``, the statistics table ``stats[H, S, A, 4]`` holding the count ``N`` (as a float, exact up to
    2^24 in float32), the Bernstein statistics (running sums of the next values and their squares) and the last
    ``beta``, in the MDP's dtype, and the member's constants (horizon ``H``, ``iota``, ``S A``).
    ``V_h(s) = min(H, max_a Q_h(s, a))`` (0 from the horizon on) is read from ``q`` rather than stored
    (:func:`table_values`): the same numbers, as ``V_h(s)`` is refreshed exactly when ``Q_h(s, .)`` changes.

    ``variant`` (static): ``"paper"``, or ``"colosseum"`` for the reference's state (:func:`init_colosseum`: counts
    from 1, and the reference's rules in :func:`bonus`, :func:`update` and :func:`table_values`). It is a static
    field, not a class attribute of a subclass, so that the two states have unequal tree structures: JAX's
    ``PyTreeDef`` equality ignored the class of a dataclass node (``jax.tree.structure`` of the two states compared
    equal with different hashes), so a jitted ``update`` could, on a rare hash-bucket collision in JAX's cache, run
    the trace of the other variant (a reference-mode test failed once that way in a full-suite run)."""

    q: jax.Array
    stats: jax.Array
    horizon: jax.Array
    iota: jax.Array
    n_pairs: jax.Array
    action_mask: jax.Array
    hparams: QLearningEpisodicHParams
    variant: Variant = struct.field(pytree_node=False, default="paper")

    @property
    def Q(self) -> jax.Array:
        return self.q

    @property
    def N(self) -> jax.Array:
        return self.stats[..., _N].astype(jnp.int32)

    @property
    def beta(self) -> jax.Array:
        return self.stats[..., _BETA]

    @property
    def V(self) -> jax.Array:
        """``V[H + 1, S]`` (row ``H`` and rows from the horizon on are 0)."""
        H = self.q.shape[-3]
        live = (jnp.arange(H) < self.horizon[..., None])[..., None]
        mask, horizon = self.action_mask[..., None, None, :], self.horizon[..., None, None]
        V = jnp.where(live, table_values(self.q, self.stats, mask, horizon, self.variant), 0.0)
        return jnp.concatenate([V, jnp.zeros_like(V[..., :1, :])], axis=-2)

    def value(self, h: jax.Array, s: jax.Array) -> jax.Array:
        """``V_h(s)`` of one unbatched state (0 from the horizon on, so ``h = H`` reads 0)."""
        i = jnp.minimum(h, self.q.shape[0] - 1)
        v = table_values(read_at(self.q, i, s), read_at(self.stats, i, s), self.action_mask, self.horizon, self.variant)
        return jnp.where(h < self.horizon, v, 0.0)


def check_hparams(hparams: QLearningEpisodicHParams) -> None:
    """Domains: ``c_1, c_2 > 0``, ``0 <= min_at <= 1``, ``0 < p < 1``, ``bernstein`` in {0, 1}."""
    check_range("c_1", hparams.c_1, 0.0, low_open=True)
    check_range("c_2", hparams.c_2, 0.0, low_open=True)
    check_range("min_at", hparams.min_at, 0.0, 1.0)
    check_range("p", hparams.p, 0.0, 1.0, low_open=True, high_open=True)
    b = np.asarray(hparams.bernstein)
    if not np.all((b == 0) | (b == 1)):
        raise ValueError(f"bernstein must be True (UCB-Bernstein) or False (UCB-Hoeffding); got {hparams.bernstein}")


def init(key: jax.Array, spec: MDPSpec, hparams: QLearningEpisodicHParams) -> QLearningEpisodicState:
    del key
    H, S, A, dtype = spec.H, spec.n_states, spec.n_actions, spec.dtype
    horizon = spec.horizon.astype(dtype)
    live = (jnp.arange(H) < spec.horizon)[:, None, None]
    n_s, n_a = valid_counts(spec.state_mask, spec.action_mask, dtype)
    q = jnp.broadcast_to(jnp.where(live, horizon, 0.0).astype(dtype), (H, S, A))
    hparams = jax.tree.map(lambda x: jnp.asarray(x, dtype), hparams)
    return QLearningEpisodicState(
        q=q,
        stats=jnp.zeros((H, S, A, 4), dtype),
        horizon=horizon,
        iota=jnp.log(n_s * n_a * spec.n_steps.astype(dtype) / hparams.p),
        n_pairs=n_s * n_a,
        action_mask=spec.action_mask,
        hparams=hparams,
    )


def bonus(
    state: QLearningEpisodicState,
    t: jax.Array,
    sum_v: jax.Array,
    sum_v2: jax.Array,
    beta_prev: jax.Array,
    alpha: jax.Array,
) -> tuple[jax.Array, jax.Array]:
    """The bonus ``b_t`` of the ``t``-th visit and the new ``beta_t``.

    ``sum_v``/``sum_v2``: sums of the ``t`` next-state values seen so far and of their squares (this visit
    included); ``beta_prev = beta_{t-1}``. Hoeffding ignores the statistics (``beta`` is then irrelevant). The
    variance term of ``beta_t`` is ``H / t (W_t + H)`` (module docstring), or for the reference's state
    (``variant="colosseum"``) ``H (sum V^2 - sum V)^2 / t^2 + H``.
    """
    hp, H, iota = state.hparams, state.horizon, state.iota
    hoeffding = hp.c_1 * jnp.sqrt(H**3 * iota / t)
    if state.variant == "colosseum":
        variance = H * (sum_v2 - sum_v) ** 2 / t**2 + H
    else:
        variance = H / t * (jnp.maximum(sum_v2 / t - (sum_v / t) ** 2, 0.0) + H)
    beta = jnp.minimum(
        hp.c_1 * (jnp.sqrt(variance * iota) + jnp.sqrt(H**7 * state.n_pairs) * iota / t),
        hp.c_2 * jnp.sqrt(H**3 * iota / t),
    )
    bernstein = (beta - (1.0 - alpha) * beta_prev) / (2.0 * alpha)
    return jnp.where(hp.bernstein > 0, bernstein, hoeffding), beta


def update(state: QLearningEpisodicState, tr: Transition) -> QLearningEpisodicState:
    """One Q-learning step at ``(h, s, a)`` (module docstring).

    For the reference's state (``variant="colosseum"``, counts from 1) its rules: the variance term
    of :func:`bonus` and the swapped weights ``Q <- alpha_t Q + (1 - alpha_t) (r + V_{h+1}(s') + b_t)``; its refresh
    ``V_h(s) <- min(H, max_a Q_h(s, a))`` is implicit (:func:`table_values` reads ``V`` off the table).
    """
    assert_transition(tr)
    h, s, a = tr.h, tr.obs, tr.action
    row = read_at(state.stats, h, s, a)
    t = row[_N] + 1.0
    H = state.horizon
    alpha = jnp.maximum(state.hparams.min_at, (H + 1.0) / (H + t))
    v_next = state.value(h + 1, tr.next_obs)  # 0 at the end of the episode
    sum_v, sum_v2 = row[_SUM_V] + v_next, row[_SUM_V2] + v_next**2
    b, beta = bonus(state, t, sum_v, sum_v2, row[_BETA], alpha)
    target = tr.reward.astype(t.dtype) + v_next + b
    q_old = read_at(state.q, h, s, a)
    if state.variant == "colosseum":
        q = alpha * q_old + (1.0 - alpha) * target
    else:
        q = (1.0 - alpha) * q_old + alpha * target
    return state.replace(
        q=write_at(state.q, q, h, s, a), stats=write_at(state.stats, jnp.stack([t, sum_v, sum_v2, beta]), h, s, a)
    )


def act(key: jax.Array, state: QLearningEpisodicState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """Greedy in ``Q_h(obs, .)``, exact ties at random (one uniform draw)."""
    assert_observation(obs, h)
    return greedy_action_single_draw(key, read_at(state.q, h, obs), state.action_mask)


def policy(state: QLearningEpisodicState) -> jax.Array:
    """Greedy one-hot policy of ``Q``, ``[H, S, A]`` (lowest-index ties)."""
    return dp.greedy(state.Q, state.action_mask)


def greedy_actions(state: QLearningEpisodicState) -> jax.Array:
    """:func:`policy` as action indices, ``[H, S]`` (what the runner compares and evaluates)."""
    return dp.greedy_actions(state.Q, state.action_mask)


Q_LEARNING_EPISODIC = Agent(
    name="q_learning_episodic",
    episodic=True,
    default_hparams=QLearningEpisodicHParams(),
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


def init_colosseum(key: jax.Array, spec: MDPSpec, hparams: QLearningEpisodicHParams) -> QLearningEpisodicState:
    """The reference's state (``variant="colosseum"``): counts start at 1 (``Q = H`` as in :func:`init`; ``V = 0``,
    :func:`table_values`); :func:`bonus` and :func:`update` apply the reference's rules to it."""
    state = init(key, spec, hparams)
    return state.replace(stats=state.stats.at[..., _N].set(1.0), variant="colosseum")


# The same update, with the reference's rules for the reference's state (:func:`update`).
Q_LEARNING_EPISODIC_COLOSSEUM = dataclasses.replace(
    Q_LEARNING_EPISODIC, name="q_learning_episodic@colosseum", init=init_colosseum
)
