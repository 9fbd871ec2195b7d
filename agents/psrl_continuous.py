"""Optimistic posterior sampling for continuous (average-reward) MDPs (Agrawal & Jia 2017; paper §3.3; docs/agents.md
§4).

The agent keeps the posteriors of :mod:`agents.posteriors` (Dirichlet transitions with prior ``1/S`` per real next
state, Normal-Gamma rewards with prior ``[rewards_prior_mean, 1, 1, 1]``) and works in epochs (doubling trick,
:mod:`agents.epochs`). At the start of every epoch it draws ``psi`` candidate kernels per pair and plans on the
*extended MDP* whose action ``(a, k)`` in ``s`` has candidate ``k``'s kernel for ``(s, a)`` and reward ``R~(s, a)``
(one posterior draw per pair, shared by the candidates); it then executes the real action ``a`` of the best extended
action until the epoch ends. Maximising over ``psi`` draws makes posterior sampling optimistic.

Constants (``p = failure_prob``, ``T = spec.n_steps``, ``S``/``A`` the real numbers of states and actions):

* ``psi = min(60, max(2, floor(psi_weight S ln(S A / p))))`` candidates per pair (the reference's formula); the
  static buffer size ``max_psi`` (default 60) truncates it further if smaller;
* ``omega = omega_weight ln(T / p)``, ``kappa = kappa_weight ln(T / p)``;
* ``eta = max(5, min(10 S, eta_weight (sqrt(T S / A) + 12 omega S^4)))``;
* if ``S^2 A > 6 000 000`` optimism is switched off (``psi = 1``, every pair sampled from its posterior), as in the
  reference.

Candidate kernels of ``(s, a)`` with ``N(s, a)`` visits:

* ``N(s, a) >= eta``: independent posterior draws ``Dirichlet(1/S + N(s, a, .))`` (or Agrawal & Jia's scaled
  posterior ``Dirichlet((N(s, a, .) + omega) / kappa)`` when ``scaled_dirichlet``);
* ``N(s, a) < eta`` ("simple optimistic sampling"): with ``p_hat = N(s, a, .) / max(1, N(s, a))``,
  ``p^- = p_hat - min(sqrt(3 p_hat ln(4S) / N') + 3 ln(4S) / N', p_hat)`` (``N' = max(1, N(s, a))``), and each
  candidate puts the missing mass ``1 - sum p^-`` on one next state drawn uniformly among the real states,
  independently per pair and candidate (one uniform index over the real states per pair and candidate,
  :func:`jaxmdp.sampling.fused_random.uniform_index`).

Planning: the extended MDP is solved for ``discount`` (default 0.99, as the reference): by policy iteration with exact
(linear-solve) evaluation, warm-started from the previous epoch's values, rather than by value iteration to ``1e-3``.
Its stopping rule (:func:`jaxmdp.dynamic_programming.policy_iteration_by`, no switch gains more than ``eps = 1e-5 (1 +
max|V|)`` in ``Q``) bounds the plan's values by ``V* - eps / (1 - discount) <= u <= V*``: at ``discount = 0.99`` up to
``1e-3 max|V|`` below the optimum when actions are nearly tied (float32 cannot resolve such ties much better), with
``V*`` typically met to float32 precision. ``discount = 1`` asks for Agrawal & Jia's gain-optimal policy instead, by
relative value iteration with the span stopping rule (``plan_tol``, at most ``plan_max_iter`` sweeps). It is not the
default: the sampled extended MDPs are often nearly decomposable (simple optimistic sampling draws deterministic rows,
and posterior draws with the ``1/S`` prior put ``1e-30``-sized mass on most states), their optimal gain then depends on
the state and relative value iteration needs thousands to hundreds of thousands of sweeps (one 3 000-step run on
RiverSwim 25: median 44 sweeps per plan, maximum 27 230) -- and a batched plan waits for its slowest member. The agent
acts with ``Q(s, a) = max_k Q_ext(s, (a, k))``, i.e. the real action of the best extended action.

The plan never builds the extended MDP's ``[S, A max_psi, S]`` kernel: its candidates and its policy iteration are
those of :mod:`agents.extended_policy_iteration`, which states their structure and costs. The agent state is
``O(S A K)`` (counts at the successor slots, no dense ``[S, A, S]`` table). Results do not change as long as
``max_psi >= psi``, but ``max_psi`` (a static buffer size) still sets the slot loops' length, so set it to :func:`psi`
of the MDPs at hand (e.g. 2 for RiverSwim 25 at the defaults).

Policy estimate (for regret), as the reference (docs/agents.md §4): posterior means (Dirichlet mean, ``mu``),
``policy_discount``-discounted optimal values (0.99, solved exactly), greedy ``[S, A]``; the backups run on each
pair's observed next states plus the prior's uniform part (:func:`posterior_mean_kernel`, ``O(S A K)``).

Differences from the reference (Colosseum), each deliberate:

* The reward of extended action ``(a, k)`` is the draw of its own real action ``a`` (the reference tiles the
  ``S x A`` reward draw so that extended action ``j = a psi + k`` gets the reward of real action ``j mod A``).
* The simple optimistic sampling uses the pair's visit count ``N(s, a)`` in the deviation term, as Agrawal & Jia do
  (the reference divides by the per-next-state count ``N(s, a, s')``), and draws the state receiving the missing mass
  independently per pair and candidate (the reference shares one state per candidate across all pairs).
* Planning is policy iteration to the precision above instead of value iteration stopped at ``1e-3`` from zero.
* Dirichlet draws are normalised exactly and computed in log space; reward draws are always finite.

``PSRL_CONTINUOUS_COLOSSEUM`` (``agents.get("psrl_continuous", variant="colosseum")``) restores the first two and the
``sum + 1e-5`` normalisation; its planning stays exact (reference mode, docs/agents.md).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from agents import estimated_model as em
from agents.epochs import EpochSchedule, epoch_schedule, record_visit, start_epoch
from agents.posteriors import (
    NormalGamma,
    dirichlet_concentration,
    dirichlet_mean,
    normal_gamma_mean,
    normal_gamma_observe,
    normal_gamma_prior,
)
from agents.extended_policy_iteration import (  # noqa: F401 (re-exported: the planner's names, as before)
    BAND_TARGETS,
    JUMP_STATES,
    KEEP_LIMIT,
    at_eta,
    Draws,
    best_candidates,
    candidate_kernels,
    colosseum_extended_rewards,
    draws,
    extended_draws,
    extended_mdp,
    extended_policy_iteration,
)
from agents.tabular_common import copy_action_zero, discounted_greedy_policy, greedy_action, only_if
from jaxmdp import dynamic_programming as dp
from jaxmdp import struct
from jaxmdp._asserts import assert_observation, assert_transition
from jaxmdp._checks import VARIANTS, Variant, check_int, check_range
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, RunnerHints, Transition, where_due

__all__ = [
    "PSRLContinuousHParams",
    "PSRLContinuousState",
    "Constants",
    "constants",
    "psi",
    "Draws",
    "draws",
    "candidate_kernels",
    "extended_policy_iteration",
    "extended_mdp",
    "only_if",
    "colosseum_extended_rewards",
    "PSRL_CONTINUOUS",
    "PSRL_CONTINUOUS_COLOSSEUM",
]

# Above this many kernel entries the reference gives up optimism (one posterior draw per pair).
_OPTIMISM_LIMIT = 6_000_000
# The reference's cap on the number of candidates.
_PSI_CAP = 60


class PSRLContinuousHParams(struct.PyTreeNode):
    """Hyperparameters; the five weights default to the benchmark's tuned values (docs/agents.md §4, cached).

    Attributes:
      rewards_prior_mean: ``mu0`` of the Normal-Gamma reward prior ``[mu0, reward_prior_count,
        reward_prior_precision, reward_prior_precision_count]`` (searched in ``U(0, 1.2)``).
      psi_weight, omega_weight, kappa_weight, eta_weight: weights of the constants ``psi``, ``omega``, ``kappa``,
        ``eta`` (module docstring). ``kappa`` only matters with ``scaled_dirichlet``.
      failure_prob: ``p`` in the constants (0.05 in the benchmark).
      discount: planning criterion: ``< 1`` discounted (default 0.99, the reference), ``1`` average reward.
      plan_tol, aperiodicity, plan_max_iter: span tolerance, aperiodicity weight and sweep limit of the
        average-reward planner (unused when ``discount < 1``).
      policy_discount: discount of the policy estimate.
      max_psi: static size of the candidate buffer (``>= psi`` changes nothing; smaller truncates ``psi``).
      scaled_dirichlet: static; draw from Agrawal & Jia's ``Dirichlet((N + omega) / kappa)`` instead of the
        Bayesian posterior ``Dirichlet(1/S + N)`` (the reference's choice; its tuned ``kappa`` was never used).
    """

    rewards_prior_mean: float | jax.Array = 0.23589883401606418
    psi_weight: float | jax.Array = 0.016737988780906453
    omega_weight: float | jax.Array = 0.1104641036501887
    kappa_weight: float | jax.Array = 2.694052439968039
    eta_weight: float | jax.Array = 1.3826913305347895e-07
    failure_prob: float | jax.Array = 0.05
    reward_prior_count: float | jax.Array = 1.0
    reward_prior_precision: float | jax.Array = 1.0
    reward_prior_precision_count: float | jax.Array = 1.0
    discount: float | jax.Array = 0.99
    plan_tol: float | jax.Array = 1e-3
    aperiodicity: float | jax.Array = 0.5
    policy_discount: float | jax.Array = 0.99
    max_psi: int = struct.field(pytree_node=False, default=60)
    plan_max_iter: int = struct.field(pytree_node=False, default=100_000)
    scaled_dirichlet: bool = struct.field(pytree_node=False, default=False)


class Constants(struct.PyTreeNode):
    """Derived constants of one agent (module docstring): ``psi`` (int), ``omega``, ``kappa``, ``eta``."""

    psi: jax.Array
    omega: jax.Array
    kappa: jax.Array
    eta: jax.Array


class PSRLContinuousState(struct.PyTreeNode):
    """Counts of the observed next states (``K = spec.max_successors`` slots per pair, :mod:`agents.estimated_model`),
    epoch counters, reward posterior, the epoch's ``Q`` and bias ``u``, constants and masks.

    No dense ``[S, A, S]`` counts: the slots hold the same counts (:attr:`counts` rebuilds them), and a dense table
    in the state would be moved in and out of every planning round, planning or not (docs/performance.md, Planning
    rounds). The slots miss counts only if a pair meets more next states than
    ``spec.max_successors`` promised (a hand-made spec below the MDP's; never with
    :func:`~jaxmdp.experiment.agent_interface.spec_of`): ``successors.overflowed`` then records it, the agent goes on
    with the counts it kept, and the runner warns (the ``slots_overflowed`` diagnostic)."""

    successors: em.SuccessorCounts
    schedule: EpochSchedule
    rewards: NormalGamma
    Q: jax.Array
    u: jax.Array
    plan_due: jax.Array
    plan_iterations: jax.Array
    plan_converged: jax.Array
    plans_unconverged: jax.Array  # plans whose relative value iteration stopped at plan_max_iter (int32 count)
    constants: Constants
    state_mask: jax.Array
    action_mask: jax.Array
    hparams: PSRLContinuousHParams

    @property
    def counts(self) -> jax.Array:
        """The visit counts ``N(s, a, s')`` as a dense ``[..., S, A, S]`` table, rebuilt from the slots (inspection,
        the dense reference routes; the plan and the policy estimate read the slots)."""
        return em.dense_counts(self.successors)


def check_hparams(hparams: PSRLContinuousHParams) -> None:
    """Validate on the host; docs/agents.md §4's search space lies inside these domains."""
    check_range("rewards_prior_mean", hparams.rewards_prior_mean)
    check_range("psi_weight", hparams.psi_weight, 0.0, low_open=True)
    check_range("omega_weight", hparams.omega_weight, 0.0, low_open=True)
    check_range("kappa_weight", hparams.kappa_weight, 0.0, low_open=True)
    check_range("eta_weight", hparams.eta_weight, 0.0)
    check_range("failure_prob", hparams.failure_prob, 0.0, 1.0, low_open=True, high_open=True)
    check_range("reward_prior_count", hparams.reward_prior_count, 0.0, low_open=True)
    check_range("reward_prior_precision", hparams.reward_prior_precision, 0.0, low_open=True)
    check_range("reward_prior_precision_count", hparams.reward_prior_precision_count, 0.0, low_open=True)
    check_range("discount", hparams.discount, 0.0, 1.0, low_open=True)
    check_range("plan_tol", hparams.plan_tol, 0.0, low_open=True)
    check_range("aperiodicity", hparams.aperiodicity, 0.0, 1.0, low_open=True)
    check_range("policy_discount", hparams.policy_discount, 0.0, 1.0, low_open=True, high_open=True)
    check_int("max_psi", hparams.max_psi, 1, _PSI_CAP)
    check_int("plan_max_iter", hparams.plan_max_iter, 1)


def constants(hparams: PSRLContinuousHParams, n_states, n_actions, n_steps) -> Constants:
    """The derived constants for ``S = n_states``, ``A = n_actions`` real states/actions and ``T = n_steps``."""
    dtype = jnp.result_type(float)
    S, A, T = (jnp.asarray(x, dtype) for x in (n_states, n_actions, n_steps))
    p = hparams.failure_prob
    raw = jnp.floor(hparams.psi_weight * S * jnp.log(S * A / p))
    optimistic = S * S * A <= _OPTIMISM_LIMIT
    n_psi = jnp.minimum(jnp.clip(raw, 2, _PSI_CAP), hparams.max_psi)
    n_psi = jnp.where(optimistic, n_psi, 1).astype(jnp.int32)
    log_tp = jnp.log(T / p)
    omega = hparams.omega_weight * log_tp
    eta = jnp.maximum(5.0, jnp.minimum(10.0 * S, hparams.eta_weight * (jnp.sqrt(T * S / A) + 12.0 * omega * S**4)))
    return Constants(psi=n_psi, omega=omega, kappa=hparams.kappa_weight * log_tp, eta=jnp.where(optimistic, eta, 0.0))


def psi(hparams: PSRLContinuousHParams, n_states: int, n_actions: int) -> int:
    """Host-side number of candidates ``psi`` without the ``max_psi`` truncation (the largest over a grid).

    Use it to size the buffer tightly, e.g. ``hparams.replace(max_psi=psi(hparams, 25, 2))``.
    """
    w = np.asarray(hparams.psi_weight, np.float64)
    p = np.asarray(hparams.failure_prob, np.float64)
    if n_states * n_states * n_actions > _OPTIMISM_LIMIT:
        return 1
    raw = np.floor(w * n_states * np.log(n_states * n_actions / p))
    return int(np.max(np.clip(raw, 2, _PSI_CAP)))


def init(key: jax.Array, spec: MDPSpec, hparams: PSRLContinuousHParams) -> PSRLContinuousState:
    """A fresh agent: prior posteriors, derived constants and a plan due before the first action."""
    del key
    if spec.H is not None:
        raise ValueError("PSRL continuous is a continuous-MDP agent (spec.H must be None)")
    S, A = spec.n_states, spec.n_actions
    dtype = jnp.result_type(float)
    rewards = normal_gamma_prior(
        (S, A),
        hparams.rewards_prior_mean,
        hparams.reward_prior_count,
        hparams.reward_prior_precision,
        hparams.reward_prior_precision_count,
        dtype,
    )
    consts = constants(hparams, jnp.sum(spec.state_mask), jnp.sum(spec.action_mask), spec.n_steps)
    return PSRLContinuousState(
        successors=em.empty_counts(S, A, spec.max_successors, spec.state_order, spec.bandwidth),
        schedule=epoch_schedule(S, A),
        rewards=rewards,
        Q=jnp.zeros((S, A), dtype),
        u=jnp.zeros((S,), dtype),
        plan_due=jnp.ones((), bool),
        plan_iterations=jnp.zeros((), jnp.int32),
        plan_converged=jnp.ones((), bool),
        plans_unconverged=jnp.zeros((), jnp.int32),
        constants=consts,
        state_mask=spec.state_mask,
        action_mask=spec.action_mask,
        hparams=hparams,
    )


def act(key: jax.Array, state: PSRLContinuousState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """The real action of the best extended action: ``argmax_a max_k Q_ext(obs, (a, k))`` (random tie-break)."""
    assert_observation(obs, h)
    del h
    return greedy_action(key, state.Q[obs], state.action_mask)


def update(state: PSRLContinuousState, tr: Transition) -> PSRLContinuousState:
    """Fold the transition and reward into the posteriors and test the doubling rule on the pair played."""
    assert_transition(tr)
    s, a = tr.obs, tr.action
    schedule, ends = record_visit(state.schedule, s, a)
    return state.replace(
        successors=em.record(state.successors, s, a, tr.next_obs),
        schedule=schedule,
        rewards=normal_gamma_observe(state.rewards, (s, a), tr.reward),
        plan_due=state.plan_due | ends,
    )


def needs_plan(state: PSRLContinuousState) -> jax.Array:
    return state.plan_due


def _posterior_alpha(state: PSRLContinuousState) -> jax.Array:
    """The dense posterior concentration ``1/S + N(s, a, .)`` on the real states (the dense reference routes)."""
    dtype = state.Q.dtype
    S = jnp.sum(state.state_mask).astype(dtype)
    return dirichlet_concentration(1.0 / S, state.counts, state.state_mask)


def plan(
    key: jax.Array,
    state: PSRLContinuousState,
    *,
    variant: Variant = "paper",
    reward_variant: Variant | None = None,
    keep_limit: int = KEEP_LIMIT,
    jump_states: int | tuple[int, ...] = JUMP_STATES,
    band_targets: int | tuple[int, ...] = BAND_TARGETS,
) -> PSRLContinuousState:
    """Start an epoch: draw the extended MDP and solve it (module docstring).

    Discounted (default): policy iteration with exact evaluation (:func:`extended_policy_iteration`), started from
    the policy greedy on one backup of the previous values (optimal to the precision of the module docstring,
    typically a few linear solves). Average reward (``discount == 1``): relative value iteration with the span
    stopping rule, on the same structured backup. A no-op unless :func:`needs_plan` (the runner keeps the result only
    for members that asked). ``variant="colosseum"``: the reference's candidates (:func:`draws`) and extended rewards
    (:func:`colosseum_extended_rewards`). ``reward_variant`` (default ``variant``) sets the extended rewards' rule
    alone, so that an ablation can tell the two differences apart. ``keep_limit``: the posterior rows a plan keeps
    (:func:`draws`; the plan is the same, only its memory and the redrawing change: tests force the redrawing path
    with 0). ``jump_states``: the evaluations' elimination of jumping states (:data:`JUMP_STATES`; the plan is the
    same to float32 precision; tests force it on small MDPs); ``band_targets``: the banded evaluation's largest
    correction (:data:`~agents.extended_policy_iteration.BAND_TARGETS`, used when the spec gave the MDP's band
    order; the plan is again the same to float32 precision). While no pair is at ``eta`` the plan runs on lean draws
    (:attr:`~agents.extended_policy_iteration.Draws.lean`: the same candidates, no posterior paths).
    """
    if reward_variant not in (None, *VARIANTS):
        raise ValueError(f"reward_variant must be None, 'paper' or 'colosseum'; got {reward_variant!r}")

    def solve(st, k, lean):
        hp, mask = st.hparams, st.action_mask
        R_ext, d = extended_draws(k, st, variant=variant, reward_variant=reward_variant, keep_limit=keep_limit,
                                  lean=lean)
        gamma = jnp.asarray(hp.discount, R_ext.dtype)

        # Under vmap the hyperparameters stored in the state are batched, so this cond becomes a select that runs both
        # branches: each branch is kept cheap and well posed when its result is not the one selected.
        def discounted(_):
            res = extended_policy_iteration(d, R_ext, jnp.where(gamma < 1, gamma, 0.99), st.u, mask, jump_states,
                                            band_targets)
            return res.Q, res.V, res.iterations, res.converged

        def average(_):
            res = dp.relative_value_iteration(
                lambda u: copy_action_zero(best_candidates(d, R_ext, u, jnp.ones((), u.dtype))[0], mask),
                st.u,
                st.state_mask,
                mask,
                discount=1.0,
                tol=hp.plan_tol,
                max_iter=hp.plan_max_iter,
                aperiodicity=hp.aperiodicity,
                active=st.plan_due & (gamma >= 1),
            )
            return res.Q, res.u, res.iterations, res.converged

        return jax.lax.cond(gamma < 1, discounted, average, None)

    # Until some pair reaches eta (early in a run, where nearly all plans fall) the plan runs without the posterior
    # candidates' code and buffer (Draws.lean): the buffer of kept rows is zeroed at every plan and the posterior
    # branches cost at every backup (docs/performance.md, Continuous planning). Both paths draw the same candidates.
    any_posterior = jnp.any(at_eta(state))
    nothing = (state.Q, state.u, jnp.zeros((), jnp.int32), jnp.ones((), bool))
    lean = only_if(~any_posterior, lambda st, k: solve(st, k, True), nothing, state, key)
    Q, u, iterations, converged = only_if(any_posterior, lambda st, k: solve(st, k, False), lean, state, key)
    new = state.replace(
        Q=Q,
        u=u,
        schedule=start_epoch(state.schedule),
        plan_due=jnp.zeros((), bool),
        plan_iterations=iterations,
        plan_converged=converged,
        plans_unconverged=state.plans_unconverged + (~converged).astype(jnp.int32),
    )
    return where_due(state.plan_due, new, state)


def posterior_mean_kernel(state: PSRLContinuousState) -> em.SparseKernel:
    """The posterior-mean kernel ``(1/S + N(s, a, s')) / (1 + N(s, a))`` on the observed next states
    (:mod:`agents.estimated_model`): the counts over ``Z = 1 + N(s, a)`` at the slots and the prior's mass ``1 / Z``
    spread uniformly over the real states. The dense mean (:func:`agents.posteriors.dirichlet_mean`) divides by the
    concentrations' float sum instead, so the two agree to rounding."""
    dtype = state.Q.dtype
    n_real = jnp.sum(state.state_mask).astype(dtype)
    prior_mass = (1.0 / n_real) * n_real
    Z = prior_mass + state.schedule.visits.astype(dtype)
    succ = state.successors
    return em.SparseKernel.of(succ, succ.counts.astype(dtype) / Z[..., None], prior_mass / Z, state.state_mask)


def _dense_policy(state: PSRLContinuousState) -> jax.Array:
    """The policy estimate on the dense posterior mean: :func:`policy`'s dense reference route (tests, benchmarks)."""
    P = dirichlet_mean(_posterior_alpha(state))
    R = normal_gamma_mean(state.rewards)
    return discounted_greedy_policy(P, R, state.hparams.policy_discount, state.action_mask)


def policy(state: PSRLContinuousState) -> jax.Array:
    """Greedy ``[S, A]`` policy of the discounted optimal values of the posterior-mean MDP, its backups on the
    observed next states (:func:`posterior_mean_kernel`, :func:`agents.estimated_model.discounted_greedy_policy`)."""
    return warm_policy(state, None)[0]


def warm_policy(state: PSRLContinuousState, start: jax.Array | None) -> tuple[jax.Array, jax.Array]:
    """:func:`policy` with its value iteration started from ``start`` (``[S]``, the values the previous call returned;
    ``None``: zeros) and the exact values of the returned policy, the next call's start
    (:func:`agents.estimated_model.warm_greedy_policy`; ``RunnerHints.warm_policy``)."""
    R = normal_gamma_mean(state.rewards)
    return em.warm_greedy_policy(posterior_mean_kernel(state), R, state.hparams.policy_discount, state.action_mask,
                                 start)


def policy_start(state: PSRLContinuousState) -> jax.Array:
    """The start of the first policy estimate: zeros ``[S]`` (``RunnerHints.policy_start``)."""
    return jnp.zeros(state.Q.shape[:1], state.Q.dtype)


PSRL_CONTINUOUS = Agent(
    name="psrl_continuous",
    episodic=False,
    default_hparams=PSRLContinuousHParams(),
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
        # Epochs end member by member, so most members ask together only before the first action: the runner plans
        # in rounds only and compiles the plan once, not twice (docs/performance.md, Planning rounds).
        whole_batch_plans=0,
        # One member a round on a CPU, whatever its state's size (a cap of 0 bytes): a plan's policy iteration
        # solves a dense S x S system, and under vmap every slot waits for the slowest member's iterations, so one
        # slot a round beats several where plans fall thickest (docs/performance.md, Planning rounds).
        plan_slot_bytes=0,
    ),
)


#: Reference mode (docs/agents.md, "Reference mode"): the reference's candidate kernels and extended rewards.
PSRL_CONTINUOUS_COLOSSEUM = dataclasses.replace(
    PSRL_CONTINUOUS, name="psrl_continuous@colosseum", plan=functools.partial(plan, variant="colosseum")
)
