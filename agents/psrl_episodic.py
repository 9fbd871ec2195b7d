"""PSRL for episodic MDPs (Osband, Russo & Van Roy 2013; paper §3.3; docs/agents.md §1).

At the start of every episode the agent draws one MDP ``(P~, R~)`` from its posterior, solves it exactly by
backward induction, ``Q~_h = R~ + P~ V~_{h+1}``, ``V~_h = max_a Q~_h`` (``V~_H = 0``), and follows
``a_h = argmax_a Q~_h(s_h, a)`` for the whole episode. Posteriors (see :mod:`agents.posteriors`), independent per
``(s, a)`` and stationary across in-episode steps: ``P(.|s,a) ~ Dirichlet(transition_prior + N(s,a,.))`` and a
Normal-Gamma posterior on the mean reward with prior ``[prior_mean, reward_prior_count, reward_prior_precision,
reward_prior_precision_count]``.

Per step the reward posterior of ``(s_h, a_h)`` absorbs the reward and the Dirichlet of ``(s_h, a_h)`` the next
state. Planning (posterior sample + backward induction, ``O(H S^2 A)``) runs in :func:`plan` when :func:`needs_plan`
says an episode has ended.

Policy estimate (for regret): backward induction on the posterior means (Dirichlet mean, ``mu``), greedy, ``[H, S, A]``.

The counts live in ``K`` successor slots per pair (:class:`agents.estimated_model.SuccessorCounts`, ``K =
MDPSpec.max_successors``, one more under the ``"last_state"`` rule), not in a dense ``[S, A, S]`` table: a pair meets
no more next states than the MDP has successors, so the slots hold every count. The plan scatters them into the dense
concentration its draw needs (the same numbers, so the same draws); the posterior mean is the slots plus the prior's
uniform part, ``E[V(s')] = (sum_k N_k V(s'_k) + alpha0 sum_real V) / (alpha0 S_real + N(s, a))``, so the policy
estimate that the indicators ask for at every log costs ``O(H S A K)`` instead of ``O(H S^2 A)``, and a planning
round moves a small state instead of the dense table (docs/performance.md, Benchmark wall time).

Differences from the reference (Colosseum), each deliberate:

* The last step of an episode also updates the transition posterior (``final_transition="learn"``): here its next
  state is a real draw from the same stationary kernel, whereas the reference observes ``-1`` there. The reference
  docs/agents.md describes skips that update (``"skip"``); another version of its code, whose behaviour the paper's
  published numbers show (docs/results.md, Episodic PSRL's terminal observation), passed the ``-1`` on to its count
  vector, where numpy's index ``-1`` counted a visit to the MDP's *last* state (``"last_state"``).
* Dirichlet draws are normalised exactly (the reference divides by ``sum + 1e-5``) and computed in log space, and a
  reward draw's standard deviation is capped at ``e^30`` so it is always finite.
* Exact ties in ``Q~`` are broken with the agent's key; the policy estimate breaks ties towards the lowest action
  index (the reference re-seeds 42, docs/measures.md §1.4).

``PSRL_EPISODIC_COLOSSEUM`` (``agents.get("psrl_episodic", variant="colosseum")``) counts an episode's last
transition as a visit to the last state (``final_transition="last_state"``, the code of the published numbers) and
normalises its Dirichlet draws by ``sum + 1e-5`` (reference mode, docs/agents.md).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp

from agents import estimated_model as em
from agents.posteriors import (
    COLOSSEUM_DIRICHLET_OFFSET,
    LogGammaSampler,
    NormalGamma,
    dirichlet_concentration,
    dirichlet_sample,
    log_gamma_sample,
    normal_gamma_mean,
    normal_gamma_observe,
    normal_gamma_prior,
    normal_gamma_sample,
)
from agents.tabular_common import copy_action_zero, greedy_action
from jaxmdp import dynamic_programming as dp
from jaxmdp import struct
from jaxmdp._asserts import assert_observation, assert_transition
from jaxmdp._checks import Variant, check_range, did_you_mean
from jaxmdp.experiment.agent_interface import Agent, MDPSpec, RunnerHints, Transition, where_due

__all__ = [
    "FINAL_TRANSITIONS",
    "PSRLEpisodicHParams",
    "PSRLEpisodicState",
    "PSRL_EPISODIC",
    "PSRL_EPISODIC_COLOSSEUM",
]

#: Values of ``PSRLEpisodicHParams.final_transition``: the paper's rule, then the reference's two.
FINAL_TRANSITIONS: tuple[str, ...] = ("learn", "skip", "last_state")


class PSRLEpisodicHParams(struct.PyTreeNode):
    """Hyperparameters; defaults are the benchmark's tuned values (docs/agents.md §1, cached).

    Attributes:
      prior_mean, reward_prior_count, reward_prior_precision, reward_prior_precision_count: the Normal-Gamma reward
        prior ``[mu0, n_mu, tau0, n_tau]`` (the benchmark searches ``prior_mean ~ U(0.001, 2)``, the rest is 1).
      transition_prior: Dirichlet concentration on every real next state (searched in ``U(0.001, 2)``).
      final_transition: static; what the last step of an episode does to the transition posterior (one of
        :data:`FINAL_TRANSITIONS`): ``"learn"`` counts its real next state, ``"skip"`` nothing, ``"last_state"`` a
        visit to the MDP's last real state (module docstring).
    """

    prior_mean: float | jax.Array = 0.41854463543357456
    transition_prior: float | jax.Array = 0.32345772625210756
    reward_prior_count: float | jax.Array = 1.0
    reward_prior_precision: float | jax.Array = 1.0
    reward_prior_precision_count: float | jax.Array = 1.0
    final_transition: str = struct.field(pytree_node=False, default="learn")


class PSRLEpisodicState(struct.PyTreeNode):
    """Counts ``N[s, a, s']`` in successor slots (module docstring; ``successors.overflowed`` records a hand-made spec
    whose ``max_successors`` is below the MDP's, as for UCRL2), reward posterior, the current episode's ``Q~[H, S,
    A]`` and the spec's masks."""

    successors: em.SuccessorCounts
    rewards: NormalGamma
    Q: jax.Array
    plan_due: jax.Array
    horizon: jax.Array
    state_mask: jax.Array
    action_mask: jax.Array
    hparams: PSRLEpisodicHParams

    @property
    def counts(self) -> jax.Array:
        """The visit counts ``N(s, a, s')`` as a dense ``[..., S, A, S]`` table, rebuilt from the slots."""
        return em.dense_counts(self.successors)


def check_hparams(hparams: PSRLEpisodicHParams) -> None:
    """Validate on the host; the search space of docs/agents.md §1 lies inside these domains."""
    if hparams.final_transition not in FINAL_TRANSITIONS:
        raise ValueError(f"final_transition must be one of {FINAL_TRANSITIONS}; got {hparams.final_transition!r}"
                         f"{did_you_mean(hparams.final_transition, FINAL_TRANSITIONS)}")
    check_range("prior_mean", hparams.prior_mean)
    check_range("transition_prior", hparams.transition_prior, 0.0, low_open=True)
    check_range("reward_prior_count", hparams.reward_prior_count, 0.0, low_open=True)
    check_range("reward_prior_precision", hparams.reward_prior_precision, 0.0, low_open=True)
    check_range("reward_prior_precision_count", hparams.reward_prior_precision_count, 0.0, low_open=True)


def init(key: jax.Array, spec: MDPSpec, hparams: PSRLEpisodicHParams) -> PSRLEpisodicState:
    """A fresh agent: prior posteriors, ``Q~ = 0`` and a plan due before the first action."""
    del key
    if spec.H is None:
        raise ValueError("PSRL episodic needs an episodic MDP (spec.H is None)")
    S, A, H = spec.n_states, spec.n_actions, spec.H
    dtype = jnp.result_type(float)
    rewards = normal_gamma_prior(
        (S, A),
        hparams.prior_mean,
        hparams.reward_prior_count,
        hparams.reward_prior_precision,
        hparams.reward_prior_precision_count,
        dtype,
    )
    # The "last_state" rule counts a visit to the last real state after an episode's last step: a next state the
    # MDP's successor lists need not hold, hence one more slot.
    K = None if spec.max_successors is None else spec.max_successors + (hparams.final_transition == "last_state")
    return PSRLEpisodicState(
        successors=em.empty_counts(S, A, K),
        rewards=rewards,
        Q=jnp.zeros((H, S, A), dtype),
        plan_due=jnp.ones((), bool),
        horizon=jnp.asarray(spec.horizon, jnp.int32),
        state_mask=spec.state_mask,
        action_mask=spec.action_mask,
        hparams=hparams,
    )


def act(key: jax.Array, state: PSRLEpisodicState, obs: jax.Array, h: jax.Array) -> jax.Array:
    """``argmax_a Q~_h(obs, a)`` over valid actions (random tie-break)."""
    assert_observation(obs, h)
    return greedy_action(key, state.Q[h, obs], state.action_mask)


def update(state: PSRLEpisodicState, tr: Transition) -> PSRLEpisodicState:
    """Fold the reward (always) and the next state into the posteriors; an episode end schedules a plan.

    The step that ends an episode counts its next state, nothing, or a visit to the last real state of the MDP, as
    ``final_transition`` says (``"learn"``, ``"skip"``, ``"last_state"``)."""
    assert_transition(tr)
    rule = state.hparams.final_transition
    learn = ~tr.terminated if rule == "skip" else jnp.ones((), bool)
    next_obs = tr.next_obs
    if rule == "last_state":  # the reference's count of observation -1: numpy's x[-1] is the last (real) state
        last = state.state_mask.shape[0] - 1 - jnp.argmax(state.state_mask[::-1])
        next_obs = jnp.where(tr.terminated, last, next_obs)
    successors = em.record(state.successors, tr.obs, tr.action, next_obs, learn)
    rewards = normal_gamma_observe(state.rewards, (tr.obs, tr.action), tr.reward)
    return state.replace(successors=successors, rewards=rewards, plan_due=state.plan_due | tr.terminated)


def needs_plan(state: PSRLEpisodicState) -> jax.Array:
    return state.plan_due


def _alpha(state: PSRLEpisodicState) -> jax.Array:
    """The dense posterior concentration ``alpha0 [s' real] + N(s, a, s')`` (the draw's input)."""
    return dirichlet_concentration(state.hparams.transition_prior, state.counts, state.state_mask)


def posterior_mean_values(state: PSRLEpisodicState) -> jax.Array:
    """``Q[H, S, A]`` of backward induction on the posterior means: ``Q_h = mu + E[V_{h+1}(s')]``, ``V_H = 0``, steps
    ``h >= horizon`` worth zero (:func:`jaxmdp.dynamic_programming.finite_horizon_value_iteration`'s rule), with
    ``E`` under the Dirichlet mean read from the slots (module docstring), ``O(H S A K)``."""
    dtype = state.Q.dtype
    prior = jnp.asarray(state.hparams.transition_prior, dtype)
    mask = state.state_mask.astype(dtype)
    counts = state.successors.counts.astype(dtype)
    uniform_mass = prior * jnp.sum(mask)
    total = uniform_mass + jnp.sum(counts, axis=-1)  # the row sums of alpha
    kernel = em.SparseKernel.of(state.successors, counts / total[..., None], uniform_mass / total, state.state_mask)
    kernel = kernel.copy_action_zero(state.action_mask)
    R = copy_action_zero(normal_gamma_mean(state.rewards), state.action_mask)

    def step(V_next, h):
        Q = jnp.where(h < state.horizon, R + em.expected_next_values(kernel, V_next), 0.0)
        return jnp.max(Q, axis=-1), Q

    H = state.Q.shape[0]
    _, Q = jax.lax.scan(step, jnp.zeros(R.shape[:1], dtype), jnp.arange(H), reverse=True)
    return Q


def plan(
    key: jax.Array,
    state: PSRLEpisodicState,
    log_gamma: LogGammaSampler = log_gamma_sample,
    *,
    variant: Variant = "paper",
) -> PSRLEpisodicState:
    """Draw ``(P~, R~)`` from the posterior and solve it by backward induction (docs/agents.md §1, "Schedule").

    A no-op unless :func:`needs_plan` (the runner keeps the result only for members that asked). ``log_gamma`` is
    the posteriors' Gamma sampler (:func:`agents.posteriors.dirichlet_sample`). ``variant="colosseum"`` normalises
    the Dirichlet draws as the reference, by ``sum + 1e-5``.
    """
    k_p, k_r = jax.random.split(key)
    offset = COLOSSEUM_DIRICHLET_OFFSET if variant == "colosseum" else 0.0
    P = copy_action_zero(dirichlet_sample(k_p, _alpha(state), log_gamma, offset=offset), state.action_mask)
    R = copy_action_zero(normal_gamma_sample(k_r, state.rewards, log_gamma), state.action_mask)
    Q, _ = dp.finite_horizon_value_iteration(P, rewards=R, H=state.Q.shape[0], horizon=state.horizon)
    return where_due(state.plan_due, state.replace(Q=Q, plan_due=jnp.zeros((), bool)), state)


def policy(state: PSRLEpisodicState) -> jax.Array:
    """Greedy ``[H, S, A]`` policy of backward induction on the posterior means (:func:`posterior_mean_values`)."""
    return dp.greedy(posterior_mean_values(state), state.action_mask)


PSRL_EPISODIC = Agent(
    name="psrl_episodic",
    episodic=True,
    default_hparams=PSRLEpisodicHParams(),
    init=init,
    act=act,
    update=update,
    policy=policy,
    needs_plan=needs_plan,
    plan=plan,
    check_hparams=check_hparams,
    diagnostics=lambda state: {
        "slots_overflowed": state.successors.overflowed.astype(jnp.int32),  # a spec below the MDP's successors
    },
    hints=RunnerHints(
        # A whole batch of plans pays only when its members' episodes end together (one horizon) and it is small:
        # a plan's draw works on a dense [S, A, S] per member, and once a batch's draws leave the caches, rounds are
        # faster (docs/performance.md, Planning rounds). The state holds no dense table, so the caps are in its
        # bytes (2 MiB: 20 seeds of a 256-state, three-action MDP of the benchmark).
        whole_batch_plans=64,
        whole_batch_bytes=2 * 2**20,
        # One plan a round once a member's state passes 32 KiB (about 100 states and more in the benchmark): a
        # plan's draws over [S, A, S] are long enough to vectorise alone, so more slots save only rounds and cost
        # cache (docs/performance.md, Planning rounds).
        plan_slot_bytes=2**15,
    ),
)


#: Reference mode (docs/agents.md, "Reference mode"): the episode's last transition counts a visit to the last state
#: and the Dirichlet draws are normalised by ``sum + 1e-5``.
PSRL_EPISODIC_COLOSSEUM = dataclasses.replace(
    PSRL_EPISODIC,
    name="psrl_episodic@colosseum",
    default_hparams=PSRLEpisodicHParams(final_transition="last_state"),
    plan=functools.partial(plan, variant="colosseum"),
)
