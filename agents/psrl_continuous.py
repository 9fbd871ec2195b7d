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
  independently per pair and candidate (one ``randint`` over the real states per pair and candidate).

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

The plan never builds the extended MDP's ``[S, A max_psi, S]`` kernel (:func:`draws`, :func:`extended_policy_iteration`;
:func:`candidate_kernels` and :func:`extended_mdp` materialise it for tests). A simple optimistic candidate's
expectation is ``p^-(s, a) . V + missing(s, a) V[z_k(s, a)]``, so a backup costs ``O(S A K)`` for ``p^- . V`` (``p^-``
is zero off the observed next states: it is kept at the ``K`` successor slots, :class:`Draws`) and
``O(max_psi S A)`` for the states ``z`` (kept as ``[max_psi, S, A]`` indices). Posterior candidates (pairs at ``eta``)
are Dirichlet draws: the plan keeps those of the first ``M = min(S A, 2^22 / (max_psi S))`` pairs at ``eta``
(``[max_psi, M, S]``, drawn once, only when some pair of some member of a ``vmap`` is at ``eta``); should more pairs be
at ``eta``, it uses a draw of every pair's rows instead, drawn again at each backup one slot ``[S, A, S]`` at a time
from the same keys (the same bits each time). Within ``T = 500 000`` steps at most ``T / eta`` pairs reach ``eta``,
fewer than ``M`` at every size of the benchmark. An improvement step keeps per pair the best candidate (value and slot)
and per state the best real action, a policy being a real action and a candidate slot per state (:class:`_Choice`); an
evaluation solves ``(I - gamma P_pi) V = r_pi`` for the chosen rows, built only where the solve reads them (the states
whose row is not a jump and the states jumped to, or all ``[S, S]`` when there are too many of those).
The agent state is ``O(S A K)`` (counts at the successor slots, no dense ``[S, A, S]`` table); a plan's working
memory ``O(S^2 + max_psi S A)`` per member (kept draws aside). Results do not change as long as ``max_psi >= psi``,
but ``max_psi`` (a static buffer size) still sets the slot loops' length, so set it to :func:`psi` of the MDPs at hand
(e.g. 2 for RiverSwim 25 at the defaults). With more than ``M`` pairs at ``eta`` (e.g. optimism off, where every pair
is), every backup pays ``psi`` Dirichlet draws of ``[S, A, S]``: a few per discounted plan, one per sweep of relative
value iteration.

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
from flax import struct

from agents import estimated_model as em
from agents.epochs import EpochSchedule, epoch_schedule, record_visit, start_epoch
from agents.posteriors import (
    COLOSSEUM_DIRICHLET_OFFSET,
    NormalGamma,
    dirichlet_concentration,
    dirichlet_mean,
    dirichlet_sample,
    normal_gamma_mean,
    normal_gamma_observe,
    normal_gamma_prior,
    normal_gamma_sample,
)
from agents.tabular_common import copy_action_zero, discounted_greedy_policy, greedy_action, only_if
from jaxmdp import dynamic_programming as dp
from jaxmdp._checks import VARIANTS, Variant, check_int, check_range
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, Transition, where_due
from jaxmdp.sampling import fused_random

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
    in the state was moved in and out of every planning round (4 members of 948 states: a round with an unchanged
    plan 13.4 ms with the table, 0.46 ms without; a round with the plan 46.2 -> 14.6 ms;
    docs/benchmarks/bench_plan_rounds.md). The slots miss counts only if a pair meets more next states than
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
    del h
    return greedy_action(key, state.Q[obs], state.action_mask)


def update(state: PSRLContinuousState, tr: Transition) -> PSRLContinuousState:
    """Fold the transition and reward into the posteriors and test the doubling rule on the pair played."""
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


# The posterior rows that a plan keeps: those of the first M pairs at eta, M = min(S A, KEEP_LIMIT / (max_psi S))
# (``max_psi M S`` floats, 16 MiB a member). Above M pairs at eta, the plan uses a draw of all pairs' rows instead,
# drawn again from the same keys at every backup. For T = 500 000 at most T / eta pairs reach eta: 52 at S = 948
# (eta 9 480, M = 73), 125 at S = 400 (M = 174); Taxi (108 x 6, psi 17) keeps all its 648 pairs.
KEEP_LIMIT = 1 << 22


def _p_minus(counts: jax.Array, n1: jax.Array, log4s: jax.Array, colosseum: bool) -> jax.Array:
    """Simple optimistic sampling's lower row ``p^- = p_hat - min(sqrt(3 p_hat ln(4S) / n) + 3 ln(4S) / n, p_hat)``
    at next-state counts ``counts[..., n_next]`` (float) of pairs with ``n1 = max(1, N(s, a))[..., None]`` visits;
    ``n = n1``, or (``colosseum``) the reference's per-next-state ``max(1, N(s, a, s'))``. Elementwise, so the slots'
    values equal the dense row's at the same next states, and an unobserved next state gets exactly 0."""
    p_hat = counts / n1
    n_dev = jnp.maximum(counts, 1.0) if colosseum else n1
    return p_hat - jnp.minimum(jnp.sqrt(3.0 * p_hat * log4s / n_dev) + 3.0 * log4s / n_dev, p_hat)


class Draws(struct.PyTreeNode):
    """One plan's candidates in structured form (module docstring): candidate ``k`` of ``(s, a)`` is
    ``p^-(s, a) + missing[s, a] e_z[k, s, a]`` where ``posterior[s, a]`` is False, else a Dirichlet draw from the
    posterior concentration of the pair's counts: ``kept[k, m]`` for pair ``pairs[m]`` (the first ``M`` pairs at
    ``eta``, then the fill value ``S A``), or, when more than ``M`` pairs are at ``eta`` (``overflow``), row ``(s, a)``
    of :meth:`draw`. ``active[k]``: slot ``k < psi``.

    ``p^-`` (:func:`_p_minus`) is non-zero only at observed next states, so it is held at the pair's successor slots
    (``p_minus[S, A, K]`` at ``slot_states``) and backed up in ``O(S A K)``. Nor is the dense concentration kept: the
    posterior rows are drawn from the count rows of the pairs drawn, scattered from the slots."""

    slot_counts: jax.Array  # [S, A, K] int32: N(s, a, s') at the slots
    slot_states: jax.Array  # [S, A, K] int32
    p_minus: jax.Array  # [S, A, K]: p^- at the slots
    missing: jax.Array  # [S, A]
    z: jax.Array  # [max_psi, S, A] int32, real states
    posterior: jax.Array  # [S, A] bool: N(s, a) >= eta
    concentration: jax.Array  # [3]: (prior 1/S, omega, kappa) of the posterior concentration
    state_mask: jax.Array  # [S]
    key: jax.Array
    active: jax.Array  # [max_psi] bool
    pairs: jax.Array  # [M] int32 flat pair indices s A + a
    kept: jax.Array  # [max_psi, M, S]
    offset: float = struct.field(pytree_node=False, default=0.0)
    colosseum: bool = struct.field(pytree_node=False, default=False)
    scaled: bool = struct.field(pytree_node=False, default=False)

    @property
    def any_posterior(self) -> jax.Array:
        return jnp.any(self.posterior)

    @property
    def overflow(self) -> jax.Array:
        return jnp.sum(self.posterior) > self.pairs.shape[0]

    def alpha(self, counts: jax.Array) -> jax.Array:
        """The posterior concentration of count rows ``counts[..., S]``: ``1/S + N`` on the real states, or Agrawal &
        Jia's ``(N + omega) / kappa`` (``scaled``)."""
        prior, omega, kappa = self.concentration
        if self.scaled:
            return jnp.where(self.state_mask, (counts.astype(self.missing.dtype) + omega) / kappa, 0.0)
        return dirichlet_concentration(prior, counts, self.state_mask)

    def dense_counts(self) -> jax.Array:
        """The counts ``[S, A, S]`` scattered from the slots."""
        return em.scatter_slots(self.slot_states, self.slot_counts, self.state_mask.shape[0])

    def p_minus_dense(self) -> jax.Array:
        """``p^-`` of every pair, ``[S, A, S]``, scattered from the slots (for inspection; a plan never builds it)."""
        return em.scatter_slots(self.slot_states, self.p_minus, self.state_mask.shape[0])

    def p_minus_dot(self, V: jax.Array) -> jax.Array:
        """``p^-(s, a) . V`` for every pair, ``[S, A]``: on the slots, ``O(S A K)``."""
        return jnp.sum(self.p_minus * V[self.slot_states], axis=-1)

    def p_minus_rows(self, s: jax.Array, a: jax.Array) -> jax.Array:
        """The dense rows ``p^-(s[n], a[n])``, ``[n, S]``, scattered from the slots (distinct states, so exact)."""
        return em.scatter_slots(self.slot_states[s, a], self.p_minus[s, a], self.state_mask.shape[0])

    def dirichlet(self, k: jax.Array, alpha: jax.Array) -> jax.Array:
        """Candidate ``k``'s posterior draws of concentrations ``alpha[..., S]`` (one key per candidate slot)."""
        return dirichlet_sample(jax.random.fold_in(self.key, k), alpha, offset=self.offset)

    def kept_alpha(self) -> jax.Array:
        """The concentrations ``[M, S]`` of the kept pairs, from their slots."""
        K = self.slot_states.shape[-1]
        m = jnp.minimum(self.pairs, self.missing.size - 1)
        S = self.state_mask.shape[0]
        rows = em.scatter_slots(self.slot_states.reshape(-1, K)[m], self.slot_counts.reshape(-1, K)[m], S)
        return self.alpha(rows)

    def draw(self, k: jax.Array) -> jax.Array:
        """Candidate ``k``'s posterior draws ``[S, A, S]`` for every pair, used when ``overflow``."""
        return self.dirichlet(k, self.alpha(self.dense_counts()))

    def posterior_draw(self, k: jax.Array) -> jax.Array:
        """The ``[S, A, S]`` posterior candidates ``k`` that a plan uses (rows of pairs not at ``eta`` meaningless)."""
        S = self.state_mask.shape[0]
        kept = jnp.zeros((self.missing.size, S), self.missing.dtype).at[self.pairs].set(self.kept[k], mode="drop")
        return jnp.where(self.overflow, self.draw(k), kept.reshape(self.missing.shape + (S,)))


def draws(
    key: jax.Array, state: PSRLContinuousState, *, variant: Variant = "paper", keep_limit: int = KEEP_LIMIT
) -> Draws:
    """The candidates of one plan (module docstring) without their dense kernels.

    The state receiving the missing mass is one ``randint`` (:func:`jaxmdp.sampling.fused_random.randint`) over the
    real states (``state_mask``, in index order, wherever the padding lies) per pair and slot (``variant="colosseum"``:
    per slot, shared by all pairs). The colosseum variant's deviation divides by ``max(1, N(s, a, s'))`` and its
    posterior draws are normalised by ``sum + 1e-5``. ``p^-`` is computed at the successor slots only
    (:class:`Draws`). The posterior draws of the first ``M = min(S A, keep_limit / (max_psi S))`` (at least one) pairs
    at ``eta`` are kept (``keep_limit`` floats, static; default :data:`KEEP_LIMIT`), drawn only if some pair (of any
    member of a ``vmap``) is at ``eta``; with more pairs at ``eta``, every backup draws all rows again from the same
    keys (:meth:`Draws.draw`)."""
    colosseum = variant == "colosseum"
    hp, c = state.hparams, state.constants
    dtype = state.Q.dtype
    S, A = state.Q.shape
    K = hp.max_psi
    mask = state.state_mask
    n_real = jnp.sum(mask).astype(dtype)
    N = state.schedule.visits.astype(dtype)
    n1 = jnp.maximum(N, 1.0)[..., None]
    log4s = jnp.log(4.0 * n_real)
    succ = state.successors
    p_minus = _p_minus(succ.counts.astype(dtype), n1, log4s, colosseum)
    k_dir, k_z = jax.random.split(key)
    real_states = jnp.argsort(~mask, stable=True)  # the real states first, in index order
    # jax.random.randint's draws, bit for bit, hashed in the plan's own fusion (3x faster at 60 x 948 x 3 on CPU).
    index = fused_random.randint(k_z, (K,) if colosseum else (K, S, A), 0, jnp.sum(mask).astype(jnp.int32))
    z = jnp.broadcast_to(real_states[index].reshape((K, 1, 1) if colosseum else (K, S, A)), (K, S, A))
    posterior = N >= c.eta
    M = min(S * A, max(1, keep_limit // (K * S)))
    (pairs,) = jnp.nonzero(posterior.reshape(-1), size=M, fill_value=S * A)
    out = Draws(slot_counts=succ.counts, slot_states=succ.states, p_minus=p_minus,
                missing=1.0 - jnp.sum(p_minus, axis=-1), z=z.astype(jnp.int32),
                posterior=posterior, concentration=jnp.stack([1.0 / n_real, c.omega, c.kappa]).astype(dtype),
                state_mask=mask, key=k_dir, active=jnp.arange(K) < c.psi, pairs=pairs.astype(jnp.int32),
                kept=jnp.zeros((K, M, S), dtype), offset=COLOSSEUM_DIRICHLET_OFFSET if colosseum else 0.0,
                colosseum=colosseum, scaled=hp.scaled_dirichlet)
    zeros = jnp.zeros((M, S), dtype)

    # The draws come in as an operand, so that the concentrations are computed inside the skip, once per plan that
    # draws any.
    def kept(d):
        alpha = d.kept_alpha()
        return jax.lax.map(lambda k: only_if(d.active[k], d.dirichlet, zeros, k, alpha), jnp.arange(K))

    return out.replace(kept=only_if(out.any_posterior, kept, out.kept, out))


def candidate_kernels(
    key: jax.Array, state: PSRLContinuousState, *, variant: Variant = "paper", keep_limit: int = KEEP_LIMIT
) -> jax.Array:
    """The dense ``[max_psi, S, A, S]`` candidate kernels of :func:`draws` (the same draws a plan with this key
    uses; for tests and inspection, a plan never builds them). Slots ``k >= psi`` repeat candidate 0, so they never
    change a maximum over candidates.

    ``variant="colosseum"``: the reference's simple optimistic sampling, whose deviation divides by the per-next-state
    count ``max(1, N(s, a, s'))`` and whose candidate ``k`` hands the missing mass of every pair to one shared state
    ``z_k``; posterior draws are normalised by ``sum + 1e-5``. ``keep_limit``: as for :func:`draws`."""
    d = draws(key, state, variant=variant, keep_limit=keep_limit)
    S = state.Q.shape[0]
    zeros = jnp.zeros(d.missing.shape + (S,), d.missing.dtype)
    p_minus = d.p_minus_dense()

    def one(k):
        posterior = only_if(d.any_posterior, d.posterior_draw, zeros, k)
        optimistic = p_minus + d.missing[..., None] * jax.nn.one_hot(d.z[k], S, dtype=d.missing.dtype)
        return jnp.where(d.posterior[..., None], posterior, optimistic)

    P = jax.lax.map(one, jnp.arange(d.z.shape[0]))
    return jnp.where(d.active[:, None, None, None], P, P[:1])


def extended_mdp(R: jax.Array, P: jax.Array, action_mask: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The extended MDP as a dense model (for tests and inspection; :func:`plan` uses its structure instead): action
    ``j = a * max_psi + k`` of ``s`` has candidate ``k``'s kernel of ``(s, a)`` and reward ``R[s, a]``. Returns
    ``(T[S, A max_psi, S], R[S, A max_psi], action_mask[A max_psi])``; padded actions mirror action 0."""
    K, S, A, _ = P.shape
    R = copy_action_zero(R, action_mask)
    P = jnp.where(action_mask[None, None, :, None], P, P[:, :, :1])
    T = jnp.transpose(P, (1, 2, 0, 3)).reshape(S, A * K, S)
    return T, jnp.repeat(R, K, axis=1), jnp.repeat(action_mask, K)


def colosseum_extended_rewards(R: jax.Array, psi: jax.Array, max_psi: int, action_mask: jax.Array) -> jax.Array:
    """The reference's rewards of the extended actions, ``[S, A max_psi]``: its action ``j = a psi + k`` gets
    ``R[s, j mod A]`` (``A`` real actions), the reward of another real action than the one whose kernel it uses.
    Slots ``k >= psi`` and padded actions repeat ``(a, 0)`` and ``(0, k)``, as :func:`extended_mdp` lays them out."""
    S, A = R.shape
    k = jnp.arange(max_psi)[None, :]
    a = jnp.where(action_mask, jnp.arange(A), 0)[:, None]
    j = a * psi + jnp.where(k < psi, k, 0)
    return R[:, j % jnp.sum(action_mask)].reshape(S, A * max_psi)


def _extended_rewards(R: jax.Array, state: PSRLContinuousState, variant: Variant) -> jax.Array:
    """``[max_psi, S, A]``: the reward of extended action ``(a, k)`` in ``s``, padded actions mirroring action 0."""
    S, A = R.shape
    K = state.hparams.max_psi
    if variant == "colosseum":
        R_ext = colosseum_extended_rewards(R, state.constants.psi, K, state.action_mask).reshape(S, A, K)
        return jnp.transpose(R_ext, (2, 0, 1))
    return jnp.broadcast_to(copy_action_zero(R, state.action_mask), (K, S, A))


def _kept_position(d: Draws, s: jax.Array, a: jax.Array) -> jax.Array:
    """The index ``m`` of pair ``(s, a)`` among the kept pairs ``d.pairs`` (0 for a pair not kept)."""
    A = d.missing.shape[1]
    M = d.pairs.shape[0]
    position = jnp.zeros((d.missing.size,), jnp.int32).at[d.pairs].set(jnp.arange(M, dtype=jnp.int32), mode="drop")
    return position[s * A + a]


def _best_candidates(d: Draws, R_ext: jax.Array, V: jax.Array, gamma: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Per pair the best candidate under values ``V``: ``Q[s, a] = max_k R_ext[k, s, a] + gamma row_k(s, a) . V`` and
    its ``k`` (the lowest among ties).

    Optimistic rows cost ``O(S A K)`` for ``p^- . V`` (on the successor slots) and ``O(max_psi S A)`` for ``V[z]``;
    the kept posterior rows ``O(max_psi M S)``. With more than ``M`` pairs at ``eta`` (some member of a ``vmap``), the
    posterior rows of all pairs are drawn again, one slot ``[S, A, S]`` at a time, each slot skipped past ``psi``
    (:func:`_posterior_rows` draws a chosen pair's row again from the same key)."""
    K, S, A = d.z.shape
    M = d.pairs.shape[0]
    dtype = V.dtype
    q_opt = R_ext + gamma * (d.p_minus_dot(V) + d.missing * V[d.z])  # [max_psi, S, A]
    q_opt = jnp.where(d.active[:, None, None], q_opt, -jnp.inf)
    k_opt = jnp.argmax(q_opt, axis=0).astype(jnp.int32)
    best_opt = jnp.max(q_opt, axis=0)

    pairs = jnp.minimum(d.pairs, S * A - 1)

    def kept_values(V):  # [max_psi, M]; skipped unless some pair is at eta (never at the benchmark's largest sizes)
        q = R_ext.reshape(K, S * A)[:, pairs] + gamma * jnp.sum(d.kept * V, axis=-1)
        return jnp.where(d.active[:, None], q, -jnp.inf)

    q_kept = only_if(d.any_posterior, kept_values, jnp.full((K, M), -jnp.inf, dtype), V)

    def scatter(fill, x):  # [M] values of the kept pairs -> [S, A], fill elsewhere
        return jnp.full((S * A,), fill, x.dtype).at[d.pairs].set(x, mode="drop").reshape(S, A)

    q_post = scatter(-jnp.inf, jnp.max(q_kept, axis=0))
    k_post = scatter(0, jnp.argmax(q_kept, axis=0).astype(jnp.int32))

    if M < S * A:  # static: some pairs' draws may not be kept

        # The draws come into each skip as an operand (``dd``), not by closure: closed over, the work of the
        # Dirichlet sampler that depends on the counts alone (dense, [S, A, S]) was hoisted out of every loop and ran
        # at every plan (5 members of 784 states: about 80 of 440 ms).
        def all_slots(c, dd, V):
            def better(carry, k):
                q, kk = carry
                q_k = R_ext[k] + gamma * jnp.sum(dd.draw(k) * V, axis=-1)
                up = q_k > q
                return jnp.where(up, q_k, q), jnp.where(up, k, kk)

            return jax.lax.fori_loop(0, K, lambda k, c: jax.lax.cond(dd.active[k], better, lambda c, _: c, c, k), c)

        # One skip around the whole loop, and no [S, A, S] in its carry: carried through a skip per slot, the rows
        # were copied at every slot of every backup (MiniGridRooms, 948 states: a plan 560 -> 130 ms).
        init = (jnp.full((S, A), -jnp.inf, dtype), jnp.zeros((S, A), jnp.int32))
        q_all, k_all = only_if(d.overflow, all_slots, init, init, d, V)
        q_post, k_post = jnp.where(d.overflow, q_all, q_post), jnp.where(d.overflow, k_all, k_post)

    return jnp.where(d.posterior, q_post, best_opt), jnp.where(d.posterior, k_post, k_opt)


def _posterior_rows(d: Draws, s: jax.Array, a: jax.Array, k: jax.Array) -> jax.Array:
    """The posterior rows ``[n, S]`` of candidates ``k[n]`` of pairs ``(s[n], a[n])`` at ``eta``: kept, or, with more
    pairs at ``eta`` than kept (``overflow``), drawn again from the same keys (the rows :func:`_best_candidates`
    compared)."""
    rows = d.kept[k, _kept_position(d, s, a)]
    K, S, A = d.z.shape
    if d.pairs.shape[0] >= S * A:  # static: every pair's draws are kept
        return rows

    def redraw(s, a, k, rows, dd):
        pick = lambda j, r: jnp.where((k == j)[:, None], dd.draw(j)[s, a], r)  # noqa: E731
        return jax.lax.fori_loop(0, K, pick, rows)

    return only_if(d.overflow, redraw, rows, s, a, k, rows, d)


# Above this many states, a policy's evaluation first eliminates the states whose chosen row is a jump (a simple
# optimistic candidate with all its mass missing, p^- = 0: every row of a pair visited fewer than about 3 ln(4 S)
# times), solving for the other states and the states jumped to only (dp.discounted_jump_chain_values), if they are at
# most this many; else (or with fewer states) the whole [S, S] system. At 948 states after 2 000 or 20 000 random
# steps every chosen row was a jump, to 41-49 distinct states.
# The elimination tries a system of 64 states first: a solve's pivots are applied by a loop of one step per row
# (jax.lax.linalg.lu on a CPU), so the system's size, not the states it holds, sets its cost (5 members of 784 states
# after 5 000 random steps and a warm plan: a planning round 0.20 s at 256 states, 0.16 s at 64).
JUMP_STATES = (64, 256)


class _Choice(struct.PyTreeNode):
    """A deterministic policy of the extended MDP, per state: real action, candidate, reward. Its kernel rows are
    built only where needed (:func:`_chosen_rows`): held as ``[S, S]`` rows, the policy's choice, carry and backups
    cost ``O(S^2)`` per policy-iteration step, about 9x the structured backup itself at 784 states."""

    action: jax.Array  # [S] int32
    k: jax.Array  # [S] int32: the candidate slot of the chosen pair
    reward: jax.Array  # [S]
    jump: jax.Array  # [S] int32: the state a row moves to with probability 1 (all its mass missing), else -1


def _chosen_rows(d: Draws, pi: _Choice, s: jax.Array) -> jax.Array:
    """The kernel rows ``[n, S]`` that policy ``pi`` chooses at states ``s[n]``: ``p^-(s, a) + missing(s, a)
    e_z[k, s, a]``, or the pair's posterior row ``k`` at ``eta``."""
    S = d.state_mask.shape[0]
    a, k = pi.action[s], pi.k[s]
    jumps = jax.nn.one_hot(d.z[k, s, a], S, dtype=d.missing.dtype)
    optimistic = d.p_minus_rows(s, a) + d.missing[s, a][:, None] * jumps
    posterior = only_if(d.any_posterior, _posterior_rows, jnp.zeros_like(optimistic), d, s, a, k)
    return jnp.where(d.posterior[s, a][:, None], posterior, optimistic)


def _chosen_expectations(d: Draws, pi: _Choice, V: jax.Array) -> jax.Array:
    """``row(s) . V`` for every state's chosen row: for optimistic rows ``p^- . V`` (:meth:`Draws.p_minus_dot`, the
    expression of the improvement step's backup at the same ``V``) plus the jump's value, the kept posterior rows'
    ``O(max_psi M S)`` when some pair is at ``eta``, and every chosen row (:func:`_chosen_rows`) only with more pairs at
    ``eta`` than kept."""
    K, S, A = d.z.shape
    s, a, k = jnp.arange(S), pi.action, pi.k
    optimistic = d.p_minus_dot(V)[s, a] + d.missing[s, a] * V[d.z[k, s, a]]

    def kept(dd, V):
        return jnp.sum(dd.kept * V, axis=-1)[k, _kept_position(dd, s, a)]

    posterior = only_if(d.any_posterior, kept, jnp.zeros_like(V), d, V)
    if d.pairs.shape[0] < S * A:  # static
        every = lambda dd, V: jnp.sum(_chosen_rows(dd, pi, s) * V, axis=-1)  # noqa: E731
        posterior = only_if(d.overflow, every, posterior, d, V)
    return jnp.where(d.posterior[s, a], posterior, optimistic)


def _greedy(
    d: Draws, R_ext: jax.Array, V: jax.Array, gamma: jax.Array, action_mask: jax.Array
) -> tuple[jax.Array, _Choice]:
    """One improvement step: ``Q[S, A] = max_k Q_ext(s, (a, k))`` (padded actions mirroring action 0) and the greedy
    extended action per state (lowest real action, then lowest candidate, among ties) as a :class:`_Choice`."""
    q, k = _best_candidates(d, R_ext, V, gamma)
    q = copy_action_zero(q, action_mask)
    S = q.shape[0]
    s = jnp.arange(S)
    a = dp.greedy_actions(q, action_mask)
    ka = k[s, a]
    no_mass = jnp.all(d.p_minus[s, a] == 0, axis=-1)
    jump = jnp.where(~d.posterior[s, a] & no_mass, d.z[ka, s, a], -1)
    return q, _Choice(action=a, k=ka, reward=R_ext[ka, s, a], jump=jump)


def extended_policy_iteration(
    d: Draws, R_ext: jax.Array, gamma: jax.Array, V0: jax.Array, action_mask: jax.Array,
    jump_states: int | tuple[int, ...] = JUMP_STATES,
) -> dp.ValueIterationResult:
    """Policy iteration (:func:`jaxmdp.dynamic_programming.policy_iteration_by`, exact evaluation, ``rtol = 1e-5``)
    on the extended MDP of ``d`` and rewards ``R_ext[max_psi, S, A]``, from the policy greedy on one backup of
    ``V0``. Improvement picks per pair the best candidate and per state the best real action (:func:`_greedy`);
    evaluation solves ``(I - gamma P_pi) V = r_pi`` for the chosen rows, with more states than the largest of
    ``jump_states`` (static sizes, tried in increasing order) first eliminating those whose chosen row is a jump
    (:data:`JUMP_STATES`), building the rows of the other states only. ``Q[S, A] = max_k Q_ext(s, (a, k))``."""
    sizes = sorted({jump_states} if isinstance(jump_states, int) else set(jump_states))
    S = V0.shape[0]

    def dense(pi, dd):  # dd: the draws as an operand, so that a skipped evaluation's rows are not built anyway
        return dp.discounted_chain_values(_chosen_rows(dd, pi, jnp.arange(S)), pi.reward, gamma)

    def eliminated(size):
        def values(pi, dd):
            return dp.discounted_jump_chain_values(lambda s: _chosen_rows(dd, pi, s), pi.reward, gamma, pi.jump, size)

        return values

    def evaluate(pi):
        if S <= sizes[-1]:  # static
            return dense(pi, d)
        V, fits = eliminated(sizes[0])(pi, d)
        for size in sizes[1:]:
            V, fits = only_if(~fits, eliminated(size), (V, fits), pi, d)
        return only_if(~fits, dense, V, pi, d)

    def improve(pi, V):
        q, proposal = _greedy(d, R_ext, V, gamma, action_mask)
        current = pi.reward + gamma * _chosen_expectations(d, pi, V)
        return q, jnp.max(jnp.where(action_mask, q, -jnp.inf), axis=-1) - current, proposal

    return dp.policy_iteration_by(evaluate, improve, _greedy(d, R_ext, V0, gamma, action_mask)[1])


def extended_draws(
    key: jax.Array,
    state: PSRLContinuousState,
    *,
    variant: Variant = "paper",
    reward_variant: Variant | None = None,
    keep_limit: int = KEEP_LIMIT,
) -> tuple[jax.Array, Draws]:
    """The extended MDP that :func:`plan` draws with ``key``: its rewards ``R_ext[max_psi, S, A]`` (one Normal-Gamma
    draw per pair, :func:`_extended_rewards`) and its candidates (:func:`draws`)."""
    k_r, k_p = jax.random.split(key)
    R_ext = _extended_rewards(normal_gamma_sample(k_r, state.rewards), state, reward_variant or variant)
    return R_ext, draws(k_p, state, variant=variant, keep_limit=keep_limit)


def plan(
    key: jax.Array,
    state: PSRLContinuousState,
    *,
    variant: Variant = "paper",
    reward_variant: Variant | None = None,
    keep_limit: int = KEEP_LIMIT,
    jump_states: int | tuple[int, ...] = JUMP_STATES,
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
    same to float32 precision; tests force it on small MDPs).
    """
    if reward_variant not in (None, *VARIANTS):
        raise ValueError(f"reward_variant must be None, 'paper' or 'colosseum'; got {reward_variant!r}")
    hp = state.hparams
    R_ext, d = extended_draws(key, state, variant=variant, reward_variant=reward_variant, keep_limit=keep_limit)
    mask = state.action_mask
    gamma = jnp.asarray(hp.discount, R_ext.dtype)

    # Under vmap the hyperparameters stored in the state are batched, so this cond becomes a select that runs both
    # branches: each branch is kept cheap and well posed when its result is not the one selected.
    def discounted(_):
        res = extended_policy_iteration(d, R_ext, jnp.where(gamma < 1, gamma, 0.99), state.u, mask, jump_states)
        return res.Q, res.V, res.iterations, res.converged

    def average(_):
        res = dp.relative_value_iteration(
            lambda u: copy_action_zero(_best_candidates(d, R_ext, u, jnp.ones((), u.dtype))[0], mask),
            state.u,
            state.state_mask,
            mask,
            discount=1.0,
            tol=hp.plan_tol,
            max_iter=hp.plan_max_iter,
            aperiodicity=hp.aperiodicity,
            active=state.plan_due & (gamma >= 1),
        )
        return res.Q, res.u, res.iterations, res.converged

    Q, u, iterations, converged = jax.lax.cond(gamma < 1, discounted, average, None)
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
    (:func:`agents.estimated_model.warm_greedy_policy`; ``Agent.warm_policy``)."""
    R = normal_gamma_mean(state.rewards)
    return em.warm_greedy_policy(posterior_mean_kernel(state), R, state.hparams.policy_discount, state.action_mask,
                                 start)


def policy_start(state: PSRLContinuousState) -> jax.Array:
    """The start of the first policy estimate: zeros ``[S]`` (``Agent.policy_start``)."""
    return jnp.zeros(state.Q.shape[:1], state.Q.dtype)


PSRL_CONTINUOUS = Agent(
    name="psrl_continuous",
    episodic=False,
    default_hparams=PSRLContinuousHParams(),
    init=init,
    act=act,
    update=update,
    policy=policy,
    warm_policy=warm_policy,
    policy_start=policy_start,
    needs_plan=needs_plan,
    plan=plan,
    check_hparams=check_hparams,
    diagnostics=lambda state: {
        "plans_unconverged": state.plans_unconverged,
        "slots_overflowed": state.successors.overflowed.astype(jnp.int32),  # a spec below the MDP's successors
    },
    # Epochs end member by member, so most members ask together only before the first action: the runner plans in
    # rounds only and compiles the plan once, not twice (RiverSwim-10, 24 seeds: compile 23.0 -> 12.1 s;
    # docs/benchmarks/bench_whole_batch_plans.md).
    whole_batch_plans=0,
    # One member a round on a CPU, whatever its state's size (a cap of 0 bytes): a plan's policy iteration solves a
    # dense S x S system, and under vmap every slot waits for the slowest member's iterations. Over the first 300-10 000
    # steps of 20-seed benchmark batches (108-948 states), where its plans fall thickest, one slot a round ran
    # 1.33-2.23x faster than 3-4 (docs/benchmarks/bench_plan_slots.md).
    plan_slot_bytes=0,
)


#: Reference mode (docs/agents.md, "Reference mode"): the reference's candidate kernels and extended rewards.
PSRL_CONTINUOUS_COLOSSEUM = dataclasses.replace(
    PSRL_CONTINUOUS, name="psrl_continuous@colosseum", plan=functools.partial(plan, variant="colosseum")
)
