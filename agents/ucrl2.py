"""UCRL2 for continuous (average-reward) MDPs (Jaksch, Ortner & Auer 2010; paper §3.3; docs/agents.md §3).

Optimism in the face of uncertainty, in epochs. At the start of every epoch (doubling trick,
:mod:`agents.epochs`) the agent builds the set of plausible MDPs around its estimates and plans with extended value
iteration (:mod:`agents.extended_value_iteration`) for the best gain over that set; it then follows the optimistic
policy until the epoch ends.

With ``N(s, a)`` visits, ``N' = max(1, N)``, ``N'' = max(1, N - 1)``, ``t`` the number of steps so far and
``delta_t = 1 / sqrt(t + 1)`` (so ``L = ln(2 S A (t + 1) / delta_t)``), the plausible set of ``(s, a)`` is

* rewards: ``|r - r_hat(s, a)| <= alpha_r r_max sqrt(3.5 L / N')`` (Hoeffding/Chernoff), ``r_hat`` the empirical
  mean; the optimistic reward is ``r~ = min(r_max, r_hat + width)``;
* transitions, per next state (empirical Bernstein, after Fruit et al. 2020):
  ``|p(s') - p_hat(s')| <= sqrt(alpha_p) sqrt(14 p_hat(s') (1 - p_hat(s')) L / N') + alpha_p 49 L / (3 N'')``,
  intersected with the simplex over the real states;
* an unvisited pair is unconstrained: ``r~ = r_max`` and any next-state distribution.

Per step the agent only counts (``O(K)``: ``K`` slots per pair of the observed next states, on which planning and
the policy estimate back up; ``K = MDPSpec.max_successors``); planning costs
``O(S log S + S A K log S)`` per EVI sweep. The EVI sweep count is reported in the state (``evi_iterations``,
``evi_converged``, and ``plans_unconverged``: the count of plans that stopped at ``evi_max_iter``, which the runner
reports).

Policy estimate (for regret), as the reference (docs/agents.md §3): the greedy policy of the
``policy_discount``-discounted optimal values (0.99) of the estimated MDP ``(p_hat, r_hat)``; unvisited pairs are
estimated as the reference initialises them (uniform next state, reward ``r_max``). It is solved exactly (value
iteration + policy iteration) rather than to ``1e-3``.

Differences from the reference (Colosseum), each deliberate (the algorithm as published):

* No lagging model: EVI plans with the estimates that include the epoch just finished (the reference plans with
  estimates one epoch old and only the confidence widths up to date).
* The transition confidence set is the per-next-state Bernstein box of every next state (Fruit et al.), and the
  inner maximisation is exact over box and simplex; the reference used the width of next-state index 0 for all next
  states inside an L1-style shift of mass onto the best state.
* ``r_hat`` is the unbiased empirical mean (the reference's running mean starts at ``r_max`` and double counts, e.g.
  ``(2 + x) / 3`` after one reward ``x``); ``t`` counts every step taken (the reference lags one epoch).
* EVI iterates on the aperiodic transform ``tau P + (1 - tau) I`` (same gains and policies) so it converges on
  periodic optimistic chains, warm-starts from the previous epoch's bias (the stopping rule certifies the result)
  and stops when ``span(T u - u) < evi_tol``; ``evi_tol = 1e-3`` is below Jaksch et al.'s ``1/sqrt(t_k)`` for every
  ``t_k <= 10^6``. If ``evi_max_iter`` sweeps do not meet the rule, the last iterate is used anyway (the reference
  keeps the previous epoch's policy) and ``evi_converged`` is False.
* Ties among optimistic actions are broken at random with the agent's key (like the reference's actor).

``UCRL2_COLOSSEUM`` (``agents.get("ucrl2", variant="colosseum")``) restores the first three and plans with the
reference's extended value iteration (no aperiodicity transform, from ``u = 0``, the previous epoch's ``Q`` kept when
it does not converge); its policy estimate uses the lagged model (reference mode, docs/agents.md).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from agents import estimated_model as em
from agents.epochs import EpochSchedule, epoch_schedule, record_visit, start_epoch
from agents.extended_value_iteration import (
    colosseum_extended_value_iteration,
    extended_value_iteration,
    sparse_extended_value_iteration,
)
from agents.tabular_common import discounted_greedy_policy, greedy_action, valid_counts
from jaxmdp import struct
from jaxmdp._asserts import assert_observation, assert_transition
from jaxmdp._checks import check_int, check_range
from jaxmdp.dynamic_programming import PlanResult
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, RunnerHints, Transition, where_due

__all__ = [
    "UCRL2HParams",
    "UCRL2State",
    "plausible_set",
    "confidence_widths",
    "UCRL2",
    "UCRL2ColosseumState",
    "colosseum_confidence",
    "UCRL2_COLOSSEUM",
]


class UCRL2HParams(struct.PyTreeNode):
    """Hyperparameters; ``alpha_r``/``alpha_p`` default to the benchmark's tuned values (docs/agents.md §3, cached).

    Attributes:
      alpha_r, alpha_p: scales of the reward and transition confidence widths (searched in ``U(0.1, 3)``).
      r_max: the largest reward (rewards lie in ``[0, r_max]``).
      evi_tol, aperiodicity, evi_max_iter: span tolerance, aperiodicity weight and (static) sweep limit of EVI.
      policy_discount: discount of the policy estimate.
    """

    alpha_r: float | jax.Array = 0.10294276593728004
    alpha_p: float | jax.Array = 0.9883750006754203
    r_max: float | jax.Array = 1.0
    evi_tol: float | jax.Array = 1e-3
    aperiodicity: float | jax.Array = 0.5
    policy_discount: float | jax.Array = 0.99
    evi_max_iter: int = struct.field(pytree_node=False, default=100_000)


class UCRL2State(struct.PyTreeNode):
    """Counts of the observed next states (``K`` slots per pair, :mod:`agents.estimated_model`), epoch counters,
    empirical mean rewards, step count and the current optimistic ``Q`` and bias ``u``.

    No dense ``[S, A, S]`` counts, for the reason of :class:`agents.psrl_continuous.PSRLContinuousState` (a planning
    round moved them in and out); :attr:`counts` rebuilds them from the slots. Should a pair meet more next states
    than ``spec.max_successors`` (a hand-made spec below the MDP's; never with
    :func:`~jaxmdp.experiment.agent_interface.spec_of`), ``successors.overflowed`` records it, the agent goes on
    with the counts it kept, and the runner warns (the ``slots_overflowed`` diagnostic)."""

    successors: em.SuccessorCounts
    schedule: EpochSchedule
    reward_mean: jax.Array
    t: jax.Array
    Q: jax.Array
    u: jax.Array
    plan_due: jax.Array
    evi_iterations: jax.Array
    evi_converged: jax.Array
    plans_unconverged: jax.Array  # plans whose EVI stopped at evi_max_iter (int32 count)
    state_mask: jax.Array
    action_mask: jax.Array
    hparams: UCRL2HParams

    @property
    def counts(self) -> jax.Array:
        """The visit counts ``N(s, a, s')`` as a dense ``[..., S, A, S]`` table, rebuilt from the slots (inspection,
        the dense reference routes, reference mode's lagged model)."""
        return em.dense_counts(self.successors)


def check_hparams(hparams: UCRL2HParams) -> None:
    """Validate on the host (docs/agents.md §3 searches ``alpha_r, alpha_p ~ U(0.1, 3)``)."""
    check_range("alpha_r", hparams.alpha_r, 0.0)
    check_range("alpha_p", hparams.alpha_p, 0.0)
    check_range("r_max", hparams.r_max, 0.0, low_open=True)
    check_range("evi_tol", hparams.evi_tol, 0.0, low_open=True)
    check_range("aperiodicity", hparams.aperiodicity, 0.0, 1.0, low_open=True)
    check_range("policy_discount", hparams.policy_discount, 0.0, 1.0, low_open=True, high_open=True)
    check_int("evi_max_iter", hparams.evi_max_iter, 1)


def init(key: jax.Array, spec: MDPSpec, hparams: UCRL2HParams) -> UCRL2State:
    """A fresh agent: no data, a plan due before the first action."""
    del key
    if spec.H is not None:
        raise ValueError("UCRL2 is a continuous-MDP agent (spec.H must be None)")
    S, A = spec.n_states, spec.n_actions
    dtype = jnp.result_type(float)
    return UCRL2State(
        successors=em.empty_counts(S, A, spec.max_successors, spec.state_order, spec.bandwidth),
        schedule=epoch_schedule(S, A),
        reward_mean=jnp.zeros((S, A), dtype),
        t=jnp.zeros((), jnp.int32),
        Q=jnp.zeros((S, A), dtype),
        u=jnp.zeros((S,), dtype),
        plan_due=jnp.ones((), bool),
        evi_iterations=jnp.zeros((), jnp.int32),
        evi_converged=jnp.ones((), bool),
        plans_unconverged=jnp.zeros((), jnp.int32),
        state_mask=spec.state_mask,
        action_mask=spec.action_mask,
        hparams=hparams,
    )


def act(key: jax.Array, state: UCRL2State, obs: jax.Array, h: jax.Array) -> jax.Array:
    """The optimistic policy of the epoch: ``argmax_a Q(obs, a)`` (random tie-break)."""
    assert_observation(obs, h)
    del h
    return greedy_action(key, state.Q[obs], state.action_mask)


def update(state: UCRL2State, tr: Transition) -> UCRL2State:
    """Count the transition, update the empirical mean reward and test the doubling rule on the pair played."""
    assert_transition(tr)
    s, a = tr.obs, tr.action
    schedule, ends = record_visit(state.schedule, s, a)
    n = schedule.visits[s, a].astype(state.reward_mean.dtype)
    old = state.reward_mean[s, a]
    return state.replace(
        successors=em.record(state.successors, s, a, tr.next_obs),
        schedule=schedule,
        reward_mean=state.reward_mean.at[s, a].set(old + (tr.reward - old) / n),
        t=state.t + 1,
        plan_due=state.plan_due | ends,
    )


def needs_plan(state: UCRL2State) -> jax.Array:
    return state.plan_due


def plausible_set(
    hparams: UCRL2HParams,
    visits: jax.Array,
    p: jax.Array,
    r_estimate: jax.Array,
    n_samples: jax.Array,
    state_mask: jax.Array,
    action_mask: jax.Array,
) -> tuple[jax.Array, jax.Array]:
    """``(width_p, r_tilde)``: the confidence widths of both variants (module docstring; docs/agents.md §3).

    With ``N`` = ``visits[S, A]``, ``N' = max(1, N)``, ``N'' = max(1, N - 1)``, ``S``, ``A`` the real numbers of
    states and actions and ``L = ln(2 S A (n + 1) / delta)``, ``delta = (n + 1)^(-1/2)``, ``n`` = ``n_samples``:
    ``width_p = sqrt(alpha_p) sqrt(14 p (1 - p) / N' L) + alpha_p 49 L / (3 N'')`` for each entry of ``p[S, A, k]``
    (the next-state probabilities the widths are taken at) and
    ``r_tilde = min(r_max, r_estimate + alpha_r r_max sqrt(3.5 L / N'))``. No masking of unvisited pairs here.
    """
    dtype = r_estimate.dtype
    N = visits.astype(dtype)
    n1, n2 = jnp.maximum(N, 1.0), jnp.maximum(N - 1.0, 1.0)
    S, A = valid_counts(state_mask, action_mask, dtype)
    L = jnp.log(2.0 * S * A) + 1.5 * jnp.log1p(n_samples.astype(dtype))
    width_p = jnp.sqrt(hparams.alpha_p) * jnp.sqrt(14.0 * p * (1.0 - p) / n1[..., None] * L)
    width_p = width_p + hparams.alpha_p * 49.0 * L / (3.0 * n2[..., None])
    width_r = hparams.alpha_r * hparams.r_max * jnp.sqrt(3.5 * L / n1)
    return width_p, jnp.minimum(hparams.r_max, r_estimate + width_r)


def confidence_widths(state: UCRL2State) -> tuple[jax.Array, jax.Array, jax.Array]:
    """``(p_hat[S, A, S], width_p[S, A, S], r_tilde[S, A])`` of the current plausible set (module docstring):
    :func:`plausible_set` at the empirical estimates and ``t``, unvisited pairs unconstrained."""
    N = state.schedule.visits
    visited = N > 0
    p_hat = state.counts.astype(state.reward_mean.dtype) / jnp.maximum(N, 1)[..., None]
    width_p, r_tilde = plausible_set(
        state.hparams, N, p_hat, state.reward_mean, state.t, state.state_mask, state.action_mask
    )
    width_p = jnp.where(visited[..., None], width_p, 1.0)
    return p_hat, width_p, jnp.where(visited, r_tilde, state.hparams.r_max)


def sparse_confidence(state: UCRL2State) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array, jax.Array]:
    """:func:`confidence_widths` as boxes on each pair's observed next states: ``(states, lo, hi)`` at the slots
    (``[S, A, K]``), ``room_other[S, A]`` (the upper bound at every other real state, whose ``p_hat`` is 0: there
    the width is ``alpha_p 49 L / (3 N'')``, 1 for an unvisited pair) and ``r_tilde[S, A]``; the same boxes as
    :func:`agents.extended_value_iteration.confidence_box` of :func:`confidence_widths`."""
    N = state.schedule.visits
    visited = N > 0
    dtype = state.reward_mean.dtype
    succ = state.successors
    p = succ.counts.astype(dtype) / jnp.maximum(N, 1)[..., None]
    width, r_tilde = plausible_set(
        state.hparams, N, jnp.concatenate([p, jnp.zeros_like(p[..., :1])], axis=-1), state.reward_mean, state.t,
        state.state_mask, state.action_mask,
    )
    width = jnp.where(visited[..., None], width, 1.0)
    lo = jnp.maximum(p - width[..., :-1], 0.0)
    hi = jnp.minimum(p + width[..., :-1], 1.0)
    return succ.states, lo, hi, jnp.minimum(width[..., -1], 1.0), jnp.where(visited, r_tilde, state.hparams.r_max)


def _dense_plan(state: UCRL2State) -> PlanResult:
    """Extended value iteration on the dense counts: :func:`plan`'s dense reference route (tests)."""
    p_hat, width_p, r_tilde = confidence_widths(state)
    hp = state.hparams
    return extended_value_iteration(
        p_hat, width_p, r_tilde, state.state_mask, state.action_mask, u0=state.u, tol=hp.evi_tol,
        max_iter=hp.evi_max_iter, aperiodicity=hp.aperiodicity, active=state.plan_due,
    )


def plan(key: jax.Array, state: UCRL2State) -> UCRL2State:
    """Start an epoch: extended value iteration on the current plausible set (warm-started from the last bias), its
    boxes given on each pair's observed next states (:func:`sparse_confidence`,
    :func:`agents.extended_value_iteration.sparse_extended_value_iteration`: ``O(S A K log S)`` per sweep instead of
    ``O(S^2 A)``).

    A no-op unless :func:`needs_plan` (the runner keeps the result only for members that asked; skipping the
    iterations of the others keeps a batched EVI from waiting for them).
    """
    del key
    hp = state.hparams
    res = sparse_extended_value_iteration(
        *sparse_confidence(state),
        state.state_mask,
        state.action_mask,
        u0=state.u,
        tol=hp.evi_tol,
        max_iter=hp.evi_max_iter,
        aperiodicity=hp.aperiodicity,
        active=state.plan_due,
    )
    return where_due(state.plan_due, _start_epoch(state, res.Q, res), state)


def _start_epoch(state: UCRL2State, Q: jax.Array, res: PlanResult) -> UCRL2State:
    """``state`` after a plan (both variants): ``Q``, the bias and sweep report of ``res``, a new epoch, and
    ``plans_unconverged`` counting this plan if EVI stopped at ``evi_max_iter``."""
    return state.replace(
        Q=Q,
        u=res.u,
        schedule=start_epoch(state.schedule),
        plan_due=jnp.zeros((), bool),
        evi_iterations=res.iterations,
        evi_converged=res.converged,
        plans_unconverged=state.plans_unconverged + (~res.converged).astype(jnp.int32),
    )


def estimated_model(state: UCRL2State) -> tuple[jax.Array, jax.Array]:
    """``(p_hat, r_hat)`` with unvisited pairs at a uniform next state and reward ``r_max``."""
    dtype = state.reward_mean.dtype
    N = state.schedule.visits
    visited = N > 0
    uniform = state.state_mask.astype(dtype) / jnp.sum(state.state_mask)
    P = jnp.where(visited[..., None], state.counts.astype(dtype) / jnp.maximum(N, 1)[..., None], uniform)
    return P, jnp.where(visited, state.reward_mean, state.hparams.r_max)


def sparse_estimated_model(state: UCRL2State) -> tuple[em.SparseKernel, jax.Array]:
    """:func:`estimated_model` on the observed next states (:mod:`agents.estimated_model`): the same kernel."""
    dtype = state.reward_mean.dtype
    N = state.schedule.visits
    visited = N > 0
    succ = state.successors
    kernel = em.SparseKernel.of(succ, succ.counts.astype(dtype) / jnp.maximum(N, 1)[..., None],
                                jnp.where(visited, 0.0, 1.0).astype(dtype), state.state_mask)
    return kernel, jnp.where(visited, state.reward_mean, state.hparams.r_max)


def _dense_policy(state: UCRL2State) -> jax.Array:
    """The policy estimate on the dense counts: :func:`policy`'s dense reference route (tests, benchmarks)."""
    return discounted_greedy_policy(*estimated_model(state), state.hparams.policy_discount, state.action_mask)


def policy(state: UCRL2State) -> jax.Array:
    """Greedy ``[S, A]`` policy of the discounted optimal values of the estimated MDP (``O(S A K)`` backups on the
    observed next states, :func:`agents.estimated_model.discounted_greedy_policy`)."""
    return warm_policy(state, None)[0]


def warm_policy(state: UCRL2State, start: jax.Array | None) -> tuple[jax.Array, jax.Array]:
    """:func:`policy` with its value iteration started from ``start`` (``[S]``, the values the previous call returned;
    ``None``: zeros) and the exact values of the returned policy, the next call's start
    (:func:`agents.estimated_model.warm_greedy_policy`; ``RunnerHints.warm_policy``)."""
    kernel, R = sparse_estimated_model(state)
    return em.warm_greedy_policy(kernel, R, state.hparams.policy_discount, state.action_mask, start)


def policy_start(state: UCRL2State) -> jax.Array:
    """The start of the first policy estimate: zeros ``[S]`` (``RunnerHints.policy_start``)."""
    return jnp.zeros(state.Q.shape[:1], state.Q.dtype)


UCRL2 = Agent(
    name="ucrl2",
    episodic=False,
    default_hparams=UCRL2HParams(),
    init=init,
    act=act,
    update=update,
    policy=policy,
    needs_plan=needs_plan,
    plan=plan,
    check_hparams=check_hparams,
    diagnostics=lambda state: {
        "plans_unconverged": state.plans_unconverged,
        "slots_overflowed": state.successors.overflowed.astype(jnp.int32),  # a spec below the MDP's successors
    },
    hints=RunnerHints(
        warm_policy=warm_policy,
        policy_start=policy_start,
        # Epochs end member by member: planning in rounds only is as fast, and the runner compiles the plan once,
        # not twice (docs/performance.md, Planning rounds).
        whole_batch_plans=0,
    ),
)


# ---------------------------------------------------------------------------------------------------------------
# Reference mode (docs/agents.md, "Reference mode"): the reference's update rules, as its published numbers used them
# ---------------------------------------------------------------------------------------------------------------


class UCRL2ColosseumState(UCRL2State):
    """:class:`UCRL2State` plus the reference's lagged model: ``p_model``, ``r_model`` (the estimates as of the last
    epoch end, starting at a uniform kernel and ``r_max``), the current epoch's rewards summed per pair, and
    ``iteration``, the number of rewards folded into the model (the steps before the current epoch)."""

    p_model: jax.Array
    r_model: jax.Array
    epoch_rewards: jax.Array
    iteration: jax.Array


def init_colosseum(key: jax.Array, spec: MDPSpec, hparams: UCRL2HParams) -> UCRL2ColosseumState:
    """:func:`init` with the reference's initial model: uniform next states, reward ``r_max``."""
    base = init(key, spec, hparams)
    S, A = spec.n_states, spec.n_actions
    dtype = base.reward_mean.dtype
    uniform = spec.state_mask.astype(dtype) / jnp.sum(spec.state_mask)
    return UCRL2ColosseumState(
        **{f.name: getattr(base, f.name) for f in dataclasses.fields(base)},
        p_model=jnp.broadcast_to(uniform, (S, A, S)),
        r_model=jnp.broadcast_to(jnp.asarray(hparams.r_max, dtype), (S, A)),
        epoch_rewards=jnp.zeros((S, A), dtype),
        iteration=jnp.zeros((), jnp.int32),
    )


def update_colosseum(state: UCRL2ColosseumState, tr: Transition) -> UCRL2ColosseumState:
    """:func:`update`, and the reward added to the epoch's sum for ``(s, a)``."""
    new = update(state, tr)
    return new.replace(epoch_rewards=state.epoch_rewards.at[tr.obs, tr.action].add(tr.reward))


def colosseum_confidence(state: UCRL2ColosseumState) -> tuple[jax.Array, jax.Array]:
    """``(width[S, A], r_tilde[S, A])`` of the reference's plausible set: :func:`plausible_set` at the lagged model,
    ``p = p_model(0 | s, a)`` (the width of next-state index 0 serves the whole row) and ``r_model``, with the
    up-to-date visits and ``n = iteration`` (which lags one epoch); unvisited pairs are not masked (their model is
    the initial uniform kernel and ``r_max``)."""
    width, r_tilde = plausible_set(
        state.hparams,
        state.schedule.visits,
        state.p_model[..., :1],
        state.r_model,
        state.iteration,
        state.state_mask,
        state.action_mask,
    )
    return width[..., 0], r_tilde


def plan_colosseum(key: jax.Array, state: UCRL2ColosseumState) -> UCRL2ColosseumState:
    """The reference's epoch start: extended value iteration on the lagged model with up-to-date widths
    (:func:`colosseum_confidence`; the previous ``Q`` is kept if it does not converge), then the epoch's data folded
    into the model: ``r_model <- (r_model (N + 1) + sum of the epoch's rewards) / (N + nu + 1)`` (the reference's
    running mean, which starts from ``r_max`` and counts visits twice; ``N`` the visits, ``nu`` those of the epoch),
    ``p_model <- N(s, a, .) / N`` for the pairs played in the epoch, ``iteration += sum nu``."""
    del key
    hp = state.hparams
    width, r_tilde = colosseum_confidence(state)
    res = colosseum_extended_value_iteration(
        state.p_model,
        width,
        r_tilde,
        state.state_mask,
        state.action_mask,
        tol=hp.evi_tol,
        max_iter=hp.evi_max_iter,
        active=state.plan_due,
    )
    dtype = state.r_model.dtype
    N = state.schedule.visits.astype(dtype)
    nu = state.schedule.epoch_visits.astype(dtype)
    played = nu > 0
    r_model = jnp.where(played, (state.r_model * (N + 1.0) + state.epoch_rewards) / (N + nu + 1.0), state.r_model)
    p_model = state.counts.astype(dtype) / jnp.maximum(N, 1.0)[..., None]
    new = _start_epoch(state, jnp.where(res.converged, res.Q, state.Q), res).replace(
        p_model=jnp.where(played[..., None], p_model, state.p_model),
        r_model=r_model,
        epoch_rewards=jnp.zeros_like(state.epoch_rewards),
        iteration=state.iteration + state.schedule.epoch_visits.sum(),
    )
    return where_due(state.plan_due, new, state)


def policy_colosseum(state: UCRL2ColosseumState) -> jax.Array:
    """Greedy ``[S, A]`` policy of the discounted optimal values of the lagged model ``(p_model, r_model)``."""
    return discounted_greedy_policy(state.p_model, state.r_model, state.hparams.policy_discount, state.action_mask)


UCRL2_COLOSSEUM = dataclasses.replace(
    UCRL2,
    name="ucrl2@colosseum",
    init=init_colosseum,
    update=update_colosseum,
    policy=policy_colosseum,
    # The reference's estimate: the dense route on its lagged model, started cold (no warm_policy).
    hints=dataclasses.replace(UCRL2.hints, warm_policy=None, policy_start=None),
    plan=plan_colosseum,
)
