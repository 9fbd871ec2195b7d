"""PSRL (episodic): posterior updates, planning by backward induction, probes with known answers, batching."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmdp
from agent_loop import is_river, make_runner, probe_batch, seeds
from agents import AGENTS
from agents import estimated_model as em
from agents.posteriors import dirichlet_concentration, dirichlet_mean, dirichlet_sample, normal_gamma_sample
from agents.psrl_episodic import PSRL_EPISODIC, PSRLEpisodicHParams, check_hparams, posterior_mean_values
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment.agent_interface import Transition, spec_of
from stat_checks import failure_rate_bound, key, mostly

AGENT = PSRL_EPISODIC
N_STEPS = 2000
COPIES = 4  # of the 4 probes: 16 members in lockstep
RUN = make_runner(AGENT, N_STEPS, trace=True)
START_VALUES = jax.jit(jax.vmap(
    lambda m, state: dp.finite_horizon_policy_evaluation(m, AGENT.policy(state))[1][0] @ m.P0))


def test_registered():
    assert AGENTS["psrl_episodic"] is AGENT and AGENT.episodic


def probe_passes(keys, batch=None, res=None):
    """Per member of ``keys`` (a multiple of 4; member ``i`` faces probe ``i % 4``): the policy estimate's value from
    the start is the optimal one (RiverSwim 5, H = 5, swims right 4 times and collects 1 once; the bandit, H = 2,
    pulls the 0.8 arm twice), and on RiverSwim the last 100 episodes collect the reward of 1 in more than 95 of
    them."""
    batch = probe_batch(True, keys.shape[0] // 4) if batch is None else batch  # H = 5; the bandit's horizon is 2
    res = RUN(keys, batch, AGENT.default_hparams) if res is None else res
    river = is_river(keys.shape[0])
    V = np.asarray(START_VALUES(batch, res.state))
    exploits = np.asarray(jnp.sum(res.rewards[:, -500:], axis=1)) / 100 > 0.95
    return (np.abs(V - np.where(river, 1.0, 1.6)) <= 1e-5) & (exploits | ~river)


@pytest.fixture(scope="module")
def probes():
    batch = probe_batch(True, COPIES)
    return batch, RUN, RUN(seeds(4 * COPIES), batch, AGENT.default_hparams)


# Measured: 0 of 1024 members (256 per probe, keys split from jax.random.key(10**6 + 64 i), i < 4) missed
# probe_passes (`PYTHONPATH=$PWD python tests/probe_failure_rates.py psrl_episodic --seeds 256 --chunk 64`, 25 Nov 2026):
# Clopper-Pearson bound at miss probability 1e-3, q_u = 6.7e-3 per member (stat_checks.failure_rate_bound); the test
# allows stat_checks.allowed_failures(16, q_u) = 4 failures of its 16 members: false-failure probability <= 1e-7.
Q_LEARN = failure_rate_bound(0, 1024)


@pytest.mark.statistical(p=1e-7)
def test_policy_estimates_reach_the_optimal_value(probes):
    # 16 members from stat_checks.key(0) (the fixture's run, unless $JAXMDP_TEST_SEED draws fresh ones): at most
    # stat_checks.allowed_failures(16, Q_LEARN) = 4 may miss probe_passes; false-failure probability <= 1e-7.
    batch, _, res = probes
    assert jax.eval_shape(jax.vmap(AGENT.policy), res.state).shape == (4 * COPIES, 5, 5, 3)
    keys = jax.random.split(key(0), 4 * COPIES)
    fixed = bool(np.array_equal(jax.random.key_data(keys), jax.random.key_data(seeds(4 * COPIES))))
    mostly(probe_passes(keys, batch, res if fixed else None), Q_LEARN, "PSRL episodic probes")


def test_padded_states_and_actions_are_never_used(probes):
    batch, _, res = probes
    n_actions = np.asarray(batch.action_mask.sum(-1))
    assert np.all(np.asarray(res.actions) < n_actions[:, None])
    river = is_river(4 * COPIES)
    assert int(res.state.counts[river, :, 2:].sum()) == 0
    bandits = res.state.counts[~river]
    assert int(bandits[:, 1:].sum()) == 0 and int(bandits[:, :, :, 1:].sum()) == 0
    # One plan per episode: 400 RiverSwim episodes, 1000 bandit episodes.
    np.testing.assert_array_equal(res.n_plans, np.where(river, 400, 1000))


@pytest.mark.nightly  # by default: test_runner.py's same-key test, test_properties_runner.py
def test_same_key_same_result_and_vmapped_equals_single(probes):
    batch, run, res = probes
    jax.tree.map(np.testing.assert_array_equal, run(seeds(4 * COPIES), batch, AGENT.default_hparams), res)
    i = 3
    single = make_runner(AGENT, N_STEPS, trace=True)(seeds(4 * COPIES)[i : i + 1], jax.tree.map(lambda x: x[i : i + 1], batch),
                                                     AGENT.default_hparams)
    np.testing.assert_array_equal(single.actions[0], res.actions[i])
    np.testing.assert_array_equal(single.state.counts[0], res.state.counts[i])
    np.testing.assert_allclose(single.state.Q[0], res.state.Q[i], rtol=1e-6, atol=1e-6)


def _fresh(hp, S=3, A=2, H=2):
    mdp = jaxmdp.custom_mdp(np.full((S, A, S), 1.0 / S), R=np.zeros((S, A)), H=H)
    return AGENT.init(jax.random.key(0), spec_of(mdp, 100), hp)


@pytest.mark.parametrize("rule", ["learn", "skip", "last_state"])
def test_update_closed_form(rule):
    hp = PSRLEpisodicHParams(final_transition=rule)
    state = _fresh(hp)
    assert bool(AGENT.needs_plan(state))  # a fresh agent plans before acting
    state = state.replace(plan_due=jnp.zeros((), bool))
    update = jax.jit(AGENT.update)
    # Two episodes of H = 2: (s, a, r, s', h, terminated); the real final next states (1, 0) are not the last state 2.
    stream = [(0, 1, 0.5, 2, 0, False), (2, 0, 1.0, 1, 1, True), (0, 1, 0.25, 2, 0, False), (2, 0, 0.0, 0, 1, True)]
    due = []
    for s, a, r, s2, h, term in stream:
        state = update(state, Transition(jnp.int32(s), jnp.int32(a), jnp.float32(r), jnp.int32(s2), jnp.int32(h),
                                         jnp.asarray(term)))
        due.append(bool(AGENT.needs_plan(state)))
        state = state.replace(plan_due=jnp.zeros((), bool))
    assert due == [False, True, False, True]
    expected = np.zeros((3, 2, 3), int)
    expected[0, 1, 2] = 2
    if rule == "learn":
        expected[2, 0, 1] = expected[2, 0, 0] = 1
    elif rule == "last_state":  # the reference's numpy count of observation -1
        expected[2, 0, 2] = 2
    np.testing.assert_array_equal(state.counts, expected)
    # Rewards are always learnt: prior (mu0, 1, 1/2, 1/2) then 1.0, 0.0 at (2, 0): mu = mu0 / 3 + 1/3, and
    # beta = 1/2 + (1/2)(1 (1 - mu0)^2 / 2) + (1/2)(2 (0 - mu1)^2 / 3) with mu1 = (mu0 + 1) / 2.
    mu0 = hp.prior_mean
    mu1 = (mu0 + 1) / 2
    np.testing.assert_allclose(state.rewards.mu[2, 0], (mu0 + 1.0) / 3, rtol=1e-6)
    np.testing.assert_allclose(state.rewards.beta[2, 0], 0.5 + 0.25 * (1 - mu0) ** 2 + mu1**2 / 3, rtol=1e-6)
    np.testing.assert_allclose(state.rewards.alpha[0, 1], 1.5)


def test_last_state_rule_counts_the_last_real_state_of_a_padded_spec():
    # 3 real states padded to 5: the reference's index -1 is its own last state, 2, never a padded one.
    mdp = jaxmdp.custom_mdp(np.full((3, 2, 3), 1.0 / 3), R=np.zeros((3, 2)), H=2)
    spec = spec_of(jaxmdp.pad(mdp, 5, 2, 3, 2), 100)
    state = AGENT.init(jax.random.key(0), spec, PSRLEpisodicHParams(final_transition="last_state"))
    tr = Transition(jnp.int32(1), jnp.int32(1), jnp.float32(0.0), jnp.int32(0), jnp.int32(1), jnp.asarray(True))
    counts = jax.jit(AGENT.update)(state, tr).counts
    assert counts.shape == (5, 2, 5) and int(counts[1, 1, 2]) == 1 and int(counts.sum()) == 1


def test_a_spec_below_the_mdp_s_successors_is_recorded_as_an_overflow():
    """A hand-made spec promising one successor a pair: a second next state of a pair is not counted, the slots say
    so, and the diagnostic the runner warns on counts it; the last-state rule gets a slot more."""
    mdp = jaxmdp.custom_mdp(np.full((3, 2, 3), 1.0 / 3), R=np.zeros((3, 2)), H=2)
    spec = spec_of(mdp, 100).replace(max_successors=1)
    last = AGENT.init(jax.random.key(0), spec, PSRLEpisodicHParams(final_transition="last_state"))
    assert last.successors.counts.shape == (3, 2, 2)
    state = AGENT.init(jax.random.key(0), spec, AGENT.default_hparams)
    update = jax.jit(AGENT.update)
    for s2 in (1, 1, 2):
        state = update(state, Transition(jnp.int32(0), jnp.int32(0), jnp.float32(0.0), jnp.int32(s2), jnp.int32(0),
                                         jnp.asarray(False)))
    np.testing.assert_array_equal(state.counts[0, 0], [0, 2, 0])
    assert int(AGENT.diagnostics(state)["slots_overflowed"]) == 1


def test_final_transition_rule_is_checked():
    with pytest.raises(ValueError, match=r"final_transition must be one of .*; got 'last'; did you mean 'last_state'"):
        AGENT.check_hparams(PSRLEpisodicHParams(final_transition="last"))


def _backward_induction(P, R, H):
    V = np.zeros(P.shape[0])
    Q = np.zeros((H,) + R.shape)
    for h in reversed(range(H)):
        Q[h] = R + P @ V
        V = Q[h].max(-1)
    return Q


def test_plan_is_backward_induction_on_a_posterior_draw():
    state = _fresh(AGENT.default_hparams, S=4, A=3, H=3)
    rng = np.random.default_rng(0)
    state = state.replace(successors=em.with_dense_counts(state.successors, rng.integers(0, 5, (4, 3, 4))))
    planned = jax.jit(AGENT.plan)(jax.random.key(3), state)
    k_p, k_r = jax.random.split(jax.random.key(3))
    alpha = dirichlet_concentration(AGENT.default_hparams.transition_prior, state.counts, state.state_mask)
    P = np.asarray(jax.jit(dirichlet_sample)(k_p, alpha), np.float64)
    R = np.asarray(jax.jit(normal_gamma_sample)(k_r, state.rewards), np.float64)
    np.testing.assert_allclose(planned.Q, _backward_induction(P, R, 3), rtol=1e-5, atol=1e-5)
    assert not bool(planned.plan_due)
    # A member that did not ask keeps its state.
    again = jax.jit(AGENT.plan)(jax.random.key(4), planned)
    jax.tree.map(np.testing.assert_array_equal, again.replace(hparams=planned.hparams), planned)


def test_policy_estimate_is_backward_induction_on_the_dense_posterior_mean():
    """The slots' posterior mean (counts at the slots plus the prior's uniform part) against the dense Dirichlet mean
    of the same counts, in float64, on a padded spec (5 real of 7 states, 2 real of 3 actions, horizon 3 of H = 4)
    with random counts on 3 successors a pair and random reward means: the same Q to rounding, the same policy."""
    rng = np.random.default_rng(1)
    S, A, K, H = 5, 2, 3, 3
    P = np.zeros((S, A, S))
    for s, a in np.ndindex(S, A):
        P[s, a, rng.choice(S, K, replace=False)] = rng.dirichlet(np.ones(K))
    spec = spec_of(jaxmdp.pad(jaxmdp.custom_mdp(P, R=np.zeros((S, A)), H=H), 7, 3, K, 4), 100)
    with jax.enable_x64():
        state = AGENT.init(jax.random.key(0), spec, AGENT.default_hparams)
        dense = np.zeros((7, 3, 7), np.int64)
        dense[:S, :A, :S] = rng.integers(0, 6, (S, A, S)) * (P > 0)
        mu = jnp.asarray(rng.uniform(-1, 1, (7, 3)))
        state = state.replace(successors=em.with_dense_counts(state.successors, dense),
                              rewards=state.rewards.replace(mu=mu), Q=state.Q.astype(jnp.float64))
        got = np.asarray(jax.jit(posterior_mean_values)(state))
        alpha = dirichlet_concentration(AGENT.default_hparams.transition_prior, jnp.asarray(dense), spec.state_mask)
        mean = np.array(dirichlet_mean(alpha))
        mean[:, A:] = mean[:, :1]  # padded actions copy action 0 (copy_action_zero)
        R = np.array(mu)
        R[:, A:] = R[:, :1]
        want = np.zeros((4, 7, 3))
        want[:H] = _backward_induction(mean, R, H)  # steps h >= horizon are worth zero
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(jax.jit(AGENT.policy)(state), dp.greedy(jnp.asarray(want), spec.action_mask))


def test_check_hparams_and_setting():
    check_hparams(AGENT.default_hparams)
    check_hparams(PSRLEpisodicHParams(prior_mean=jnp.linspace(0.001, 2.0, 4)))
    with pytest.raises(ValueError, match="transition_prior"):
        check_hparams(PSRLEpisodicHParams(transition_prior=0.0))
    with pytest.raises(ValueError, match="prior_mean"):
        check_hparams(PSRLEpisodicHParams(prior_mean=float("nan")))
    continuous = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=3)
    with pytest.raises(ValueError, match="episodic"):
        AGENT.init(jax.random.key(0), spec_of(continuous, 10), AGENT.default_hparams)
