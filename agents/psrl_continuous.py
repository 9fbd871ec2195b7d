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
  independently per pair and candidate.

Planning: the extended MDP (:func:`extended_mdp`) is solved for ``discount`` (default 0.99, as the reference):
by policy iteration with exact (linear-solve) evaluation, warm-started from the previous epoch's values, rather
than by value iteration to ``1e-3``. Its stopping rule (:func:`jaxmdp.dynamic_programming.policy_iteration`, no switch
gains more than ``eps = 1e-5 (1 + max|V|)`` in ``Q``) bounds the plan's values by ``V* - eps / (1 - discount) <= u <=
V*``: at ``discount = 0.99`` up to ``1e-3 max|V|`` below the optimum when actions are nearly tied (float32 cannot
resolve such ties much better), with ``V*`` typically met to float32 precision. ``discount = 1`` asks for Agrawal &
Jia's gain-optimal policy instead, by relative value iteration with the span stopping rule (``plan_tol``, at most
``plan_max_iter`` sweeps). It is not the default: the sampled extended MDPs
are often nearly decomposable (simple optimistic sampling draws deterministic rows, and posterior draws with the
``1/S`` prior put ``1e-30``-sized mass on most states), their optimal gain then depends on the state and relative
value iteration needs thousands to hundreds of thousands of sweeps (one 3 000-step run on RiverSwim 25: median 44
sweeps per plan, maximum 27 230) -- and a batched plan waits for its slowest member. The agent acts with
``Q(s, a) = max_k Q_ext(s, (a, k))``, i.e. the real action of the best extended action.

Sampling costs ``psi`` candidates (the largest ``psi`` of a batch), but memory and the planner's action count scale
with ``max_psi`` (``[max_psi, S, A, S]`` candidates per member), so set ``max_psi`` to :func:`psi` of the MDPs at
hand (e.g. 2 for RiverSwim 25 at the defaults) when running many seeds or large MDPs; results do not change as long
as ``max_psi >= psi``.

Policy estimate (for regret), as the reference (docs/agents.md §4): posterior means (Dirichlet mean, ``mu``),
``policy_discount``-discounted optimal values (0.99, solved exactly), greedy ``[S, A]``.

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
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

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
from agents.tabular_common import copy_action_zero, discounted_greedy_policy, greedy_action
from jaxmdp import dynamic_programming as dp
from jaxmdp._checks import Variant, check_int, check_range
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, Transition, where_due

__all__ = [
    "PSRLContinuousHParams",
    "PSRLContinuousState",
    "Constants",
    "constants",
    "psi",
    "candidate_kernels",
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
    """Counts, epoch counters, reward posterior, the epoch's ``Q`` and bias ``u``, constants and masks."""

    counts: jax.Array
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
        counts=jnp.zeros((S, A, S), jnp.int32),
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
        counts=state.counts.at[s, a, tr.next_obs].add(1),
        schedule=schedule,
        rewards=normal_gamma_observe(state.rewards, (s, a), tr.reward),
        plan_due=state.plan_due | ends,
    )


def needs_plan(state: PSRLContinuousState) -> jax.Array:
    return state.plan_due


def _posterior_alpha(state: PSRLContinuousState) -> jax.Array:
    dtype = state.Q.dtype
    S = jnp.sum(state.state_mask).astype(dtype)
    return dirichlet_concentration(1.0 / S, state.counts, state.state_mask)


def candidate_kernels(key: jax.Array, state: PSRLContinuousState, *, variant: Variant = "paper") -> jax.Array:
    """``[max_psi, S, A, S]`` candidate kernels (module docstring); slots ``k >= psi`` repeat candidate 0, so they
    never change a maximum over candidates.

    ``variant="colosseum"``: the reference's simple optimistic sampling, whose deviation divides by the per-next-state
    count ``max(1, N(s, a, s'))`` and whose candidate ``k`` hands the missing mass of every pair to one shared state
    ``z_k``; posterior draws are normalised by ``sum + 1e-5``."""
    colosseum = variant == "colosseum"
    hp, c = state.hparams, state.constants
    dtype = state.Q.dtype
    S, A = state.Q.shape
    mask = state.state_mask
    counts = state.counts.astype(dtype)
    if hp.scaled_dirichlet:
        alpha = jnp.where(mask, (counts + c.omega) / c.kappa, 0.0)
    else:
        alpha = _posterior_alpha(state)
    N = state.schedule.visits.astype(dtype)
    n1 = jnp.maximum(N, 1.0)[..., None]
    p_hat = counts / n1
    log4s = jnp.log(4.0 * jnp.sum(mask).astype(dtype))
    n_dev = jnp.maximum(counts, 1.0) if colosseum else n1
    p_minus = p_hat - jnp.minimum(jnp.sqrt(3.0 * p_hat * log4s / n_dev) + 3.0 * log4s / n_dev, p_hat)
    missing = 1.0 - jnp.sum(p_minus, axis=-1, keepdims=True)
    use_posterior = (N >= c.eta)[..., None]
    log_mask = jnp.where(mask, 0.0, -jnp.inf)

    # Each kind of candidate row is drawn only if some pair uses it (the other kind's values are discarded by the
    # ``where`` below): for large MDPs ``eta = 10 S`` and no pair reaches it for most of a run, so the dense Dirichlet
    # draw of every ``[S, A, S]`` entry was nearly all of a plan's time and none of its result (docs/benchmarks/
    # continuous_planning.md). The values used are the same bits as when both are drawn.
    any_posterior, any_optimistic = jnp.any(use_posterior), ~jnp.all(use_posterior)

    def draw(k):
        k_dir, k_z = jax.random.split(jax.random.fold_in(key, k))
        offset = COLOSSEUM_DIRICHLET_OFFSET if colosseum else 0.0
        posterior = only_if(
            any_posterior,
            lambda k, a: dirichlet_sample(k, a, offset=offset),
            jnp.zeros(alpha.shape, dtype),
            k_dir,
            alpha,
        )
        z_shape = () if colosseum else (S, A)
        z = only_if(
            any_optimistic,
            lambda k, logits: jax.random.categorical(k, logits, shape=z_shape),
            jnp.zeros(z_shape, jnp.int32),
            k_z,
            log_mask,
        )
        optimistic = p_minus + missing * jax.nn.one_hot(z, S, dtype=dtype)
        return jnp.where(use_posterior, posterior, optimistic)

    # Candidates k < psi only, so that sampling costs psi (the largest in a batch), not max_psi. A static loop over
    # the slots, each skipped past psi: a loop to the batched psi under vmap selected (copied) the whole
    # [max_psi, S, A, S] buffer at every candidate.
    P = jax.lax.map(lambda k: only_if(k < c.psi, draw, jnp.zeros((S, A, S), dtype), k), jnp.arange(hp.max_psi))
    return jnp.where((jnp.arange(hp.max_psi) < c.psi)[:, None, None, None], P, P[:1])


def only_if(pred: jax.Array, compute: Callable[..., Any], default: Any, *operands: Any) -> Any:
    """``compute(*operands)`` if ``pred`` else ``default`` (same structure), skipping the work when ``pred`` is False.

    A ``while_loop`` that runs its body at most once rather than a ``lax.cond``: under ``vmap`` a ``cond`` with a
    batched predicate becomes a ``select`` that computes both branches for every member, whereas a batched
    ``while_loop`` runs its body only if some member's predicate holds (then for every member, each keeping its own
    result or its ``default``). Alone (one member) it is an ordinary skip. The operands travel in the loop's carry
    through an optimisation barrier: a body computed from loop invariants alone is hoisted out of the loop by XLA
    (and then always runs)."""

    def body(carry):
        _, ops, _ = carry
        ops = jax.lax.optimization_barrier(ops)
        return jnp.zeros((), bool), ops, compute(*ops)

    return jax.lax.while_loop(lambda carry: carry[0], body, (jnp.asarray(pred, bool), operands, default))[2]


def extended_mdp(R: jax.Array, P: jax.Array, action_mask: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The extended MDP as a dense model: action ``j = a * max_psi + k`` of ``s`` has candidate ``k``'s kernel of
    ``(s, a)`` and reward ``R[s, a]``. Returns ``(T[S, A max_psi, S], R[S, A max_psi], action_mask[A max_psi])``;
    padded actions mirror action 0."""
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


def plan(key: jax.Array, state: PSRLContinuousState, *, variant: Variant = "paper") -> PSRLContinuousState:
    """Start an epoch: draw the extended MDP and solve it (module docstring).

    Discounted (default): policy iteration with exact evaluation, started from the policy greedy on one backup of
    the previous values (optimal to the precision of the module docstring, typically a few linear solves). Average
    reward (``discount == 1``): relative value iteration with the span stopping rule. A no-op unless
    :func:`needs_plan` (the runner keeps the result only for members that asked). ``variant="colosseum"``: the
    reference's candidates (:func:`candidate_kernels`) and extended rewards (:func:`colosseum_extended_rewards`).
    """
    hp = state.hparams
    S, A = state.Q.shape
    k_r, k_p = jax.random.split(key)
    R_draw = normal_gamma_sample(k_r, state.rewards)
    T, R, mask = extended_mdp(R_draw, candidate_kernels(k_p, state, variant=variant), state.action_mask)
    if variant == "colosseum":
        R = colosseum_extended_rewards(R_draw, state.constants.psi, hp.max_psi, state.action_mask)
    gamma = jnp.asarray(hp.discount, T.dtype)

    # Under vmap the hyperparameters stored in the state are batched, so this cond becomes a select that runs both
    # branches: each branch is kept cheap and well posed when its result is not the one selected.
    def discounted(_):
        g = jnp.where(gamma < 1, gamma, 0.99)
        start = dp.greedy(dp.q_values(T, state.u, g, R), mask)
        res = dp.policy_iteration(T, g, rewards=R, policy=start)
        return res.Q, res.V, res.iterations, res.converged

    def average(_):
        res = dp.relative_value_iteration(
            lambda u: R + jnp.einsum("sjt,t->sj", T, u),
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

    Q_ext, u, iterations, converged = jax.lax.cond(gamma < 1, discounted, average, None)
    new = state.replace(
        Q=jnp.max(Q_ext.reshape(S, A, hp.max_psi), axis=-1),
        u=u,
        schedule=start_epoch(state.schedule),
        plan_due=jnp.zeros((), bool),
        plan_iterations=iterations,
        plan_converged=converged,
        plans_unconverged=state.plans_unconverged + (~converged).astype(jnp.int32),
    )
    return where_due(state.plan_due, new, state)


def policy(state: PSRLContinuousState) -> jax.Array:
    """Greedy ``[S, A]`` policy of the discounted optimal values of the posterior-mean MDP."""
    P = dirichlet_mean(_posterior_alpha(state))
    R = normal_gamma_mean(state.rewards)
    return discounted_greedy_policy(P, R, state.hparams.policy_discount, state.action_mask)


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
    diagnostics=lambda state: {"plans_unconverged": state.plans_unconverged},
)


#: Reference mode (docs/agents.md, "Reference mode"): the reference's candidate kernels and extended rewards.
PSRL_CONTINUOUS_COLOSSEUM = dataclasses.replace(
    PSRL_CONTINUOUS, name="psrl_continuous@colosseum", plan=functools.partial(plan, variant="colosseum")
)
