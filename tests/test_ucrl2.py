"""UCRL2: update rule and confidence set against closed forms; probes with known answers; batching invariances."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import optimize

import jaxmdp
from agent_loop import is_river, make_runner, probe_batch, seeds
from agents import AGENTS
from agents.ucrl2 import UCRL2, UCRL2HParams, check_hparams, confidence_widths
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment.agent_interface import Transition, spec_of
from stat_checks import failure_rate_bound, key, mostly

N_STEPS = 3000
COPIES = 4  # of the 4 probes: 16 members in lockstep
RUN = make_runner(UCRL2, N_STEPS, trace=True)
GAINS = jax.jit(jax.vmap(lambda mdp, state: dp.policy_gain(mdp, UCRL2.policy(state))))


def probe_passes(keys, batch=None, res=None):
    """Per member of ``keys`` (a multiple of 4; member ``i`` faces probe ``i % 4``): the policy estimate's gain is
    the optimal one (deterministic RiverSwim earns 1 per step at its right end, the bandit's best arm 0.8), and on
    RiverSwim the last 500 steps collect the reward at the right end (mean above 0.95)."""
    batch = probe_batch(False, keys.shape[0] // 4) if batch is None else batch
    res = RUN(keys, batch, UCRL2.default_hparams) if res is None else res
    gains = np.asarray(GAINS(batch, res.state))
    optimal = np.where(is_river(keys.shape[0]), 1.0, 0.8)
    exploits = np.asarray(jnp.mean(res.rewards[:, -500:], axis=1)) > 0.95
    return (np.abs(gains - optimal) <= 1e-5) & (exploits | ~is_river(keys.shape[0]))


@pytest.fixture(scope="module")
def probes():
    batch = probe_batch(False, COPIES)
    return None, batch, RUN, RUN(seeds(4 * COPIES), batch, UCRL2.default_hparams)


def test_registered():
    assert AGENTS["ucrl2"] is UCRL2 and not UCRL2.episodic


# Measured: 0 of 1024 members (256 per probe, keys split from jax.random.key(10**6 + 64 i), i < 4) missed
# probe_passes (`PYTHONPATH=$PWD python tests/probe_failure_rates.py ucrl2 --seeds 256 --chunk 64`, 25 Nov 2026):
# Clopper-Pearson bound at miss probability 1e-3, q_u = 6.7e-3 per member (stat_checks.failure_rate_bound); the test
# allows stat_checks.allowed_failures(16, q_u) = 4 failures of its 16 members: false-failure probability <= 1e-7.
Q_LEARN = failure_rate_bound(0, 1024)


@pytest.mark.statistical(p=1e-7)
def test_policy_estimates_reach_the_optimal_gain(probes):
    # 16 members from stat_checks.key(0) (the fixture's run, unless $JAXMDP_TEST_SEED draws fresh ones): at most
    # stat_checks.allowed_failures(16, Q_LEARN) = 4 may miss probe_passes; false-failure probability <= 1e-7.
    _, batch, _, res = probes
    keys = jax.random.split(key(0), 4 * COPIES)
    fixed = bool(np.array_equal(jax.random.key_data(keys), jax.random.key_data(seeds(4 * COPIES))))
    mostly(probe_passes(keys, batch, res if fixed else None), Q_LEARN, "UCRL2 probes")


def test_padded_states_and_actions_are_never_used(probes):
    _, batch, _, res = probes
    n_actions = np.asarray(batch.action_mask.sum(-1))
    assert np.all(np.asarray(res.actions) < n_actions[:, None])
    assert int(res.state.counts[is_river(4 * COPIES), :, 2:].sum()) == 0  # RiverSwim: padded action 2
    bandits = res.state.counts[~is_river(4 * COPIES)]
    assert int(bandits[:, 1:].sum()) == 0 and np.all(np.asarray(bandits[:, 0].sum((1, 2))) == N_STEPS)
    assert int(bandits[:, :, :, 1:].sum()) == 0  # bandit: padded states


def test_same_key_same_result_and_vmapped_equals_single(probes):
    _, batch, run, res = probes
    again = run(seeds(4 * COPIES), batch, UCRL2.default_hparams)
    jax.tree.map(np.testing.assert_array_equal, again, res)
    i = 1
    single = make_runner(UCRL2, N_STEPS, trace=True)(seeds(4 * COPIES)[i : i + 1], jax.tree.map(lambda x: x[i : i + 1], batch),
                                                     UCRL2.default_hparams)
    np.testing.assert_array_equal(single.actions[0], res.actions[i])
    np.testing.assert_array_equal(single.state.counts[0], res.state.counts[i])
    np.testing.assert_allclose(single.state.Q[0], res.state.Q[i], rtol=1e-6, atol=1e-6)


@pytest.mark.nightly  # by default: test_runner_planning.py (the runner's rounds give the same results)
def test_planning_only_the_members_that_ask_gives_the_same_run(probes):
    # The test loop's plan_chunk gathers the members that need a plan into sub-batches (here one at a time).
    _, batch, _, res = probes
    chunked = make_runner(UCRL2, N_STEPS, trace=True, plan_chunk=1)(seeds(4 * COPIES), batch, UCRL2.default_hparams)
    np.testing.assert_array_equal(chunked.actions, res.actions)
    np.testing.assert_array_equal(chunked.n_plans, res.n_plans)
    np.testing.assert_allclose(chunked.state.Q, res.state.Q, rtol=1e-6, atol=1e-6)


def _spec(S=3, A=2):
    mdp = jaxmdp.custom_mdp(np.full((S, A, S), 1.0 / S), R=np.zeros((S, A)))
    return spec_of(mdp, 100)


# (s, a, r, s') of a hand-made stream, and whether the epoch ends after it (doubling rule, tests/test_epochs.py).
STREAM = [
    (0, 1, 0.5, 1, True),  # first visit of (0, 1)
    (1, 0, 0.0, 1, True),  # first visit of (1, 0)
    (1, 0, 1.0, 2, True),  # N=2, nu=1 >= 1
    (1, 0, 0.25, 1, False),  # N=3, nu=1 < 2
    (0, 1, 0.75, 2, True),  # N=2, nu=1 >= 1 (nu of (0, 1) was reset at the last plan)
]


def _feed(stream, replan=True):
    state = UCRL2.init(jax.random.key(0), _spec(), UCRL2.default_hparams)
    state = state.replace(plan_due=jnp.zeros((), bool))
    update = jax.jit(UCRL2.update)
    flags = []
    for s, a, r, s2, _ in stream:
        tr = Transition(obs=jnp.int32(s), action=jnp.int32(a), reward=jnp.float32(r), next_obs=jnp.int32(s2),
                        h=jnp.int32(0), terminated=jnp.zeros((), bool))
        state = update(state, tr)
        flags.append(bool(UCRL2.needs_plan(state)))
        if replan and flags[-1]:  # what plan does to the schedule, without solving
            state = state.replace(schedule=state.schedule.replace(epoch_visits=jnp.zeros((3, 2), jnp.int32)),
                                  plan_due=jnp.zeros((), bool))
    return state, flags


def test_update_counts_and_unbiased_reward_means():
    state, flags = _feed(STREAM)
    assert flags == [e for *_, e in STREAM]
    expected = np.zeros((3, 2, 3), int)
    for s, a, _, s2, _ in STREAM:
        expected[s, a, s2] += 1
    np.testing.assert_array_equal(state.counts, expected)
    np.testing.assert_array_equal(state.schedule.visits, expected.sum(-1))
    assert int(state.t) == len(STREAM)
    # Empirical means: (0, 1) saw 0.5, 0.75; (1, 0) saw 0, 1, 0.25; unvisited pairs stay 0.
    np.testing.assert_allclose(state.reward_mean, [[0, 0.625], [1.25 / 3, 0], [0, 0]], rtol=1e-6)


def test_confidence_widths_closed_form():
    state, _ = _feed(STREAM)
    hp = UCRL2.default_hparams
    p_hat, width_p, r_tilde = (np.asarray(x, np.float64) for x in confidence_widths(state))
    counts = np.asarray(state.counts, np.float64)
    N = counts.sum(-1)
    S, A, t = 3, 2, len(STREAM)
    delta = 1 / np.sqrt(t + 1)
    L = np.log(2 * S * A * (t + 1) / delta)
    for s in range(S):
        for a in range(A):
            if N[s, a] == 0:
                assert r_tilde[s, a] == hp.r_max and np.all(width_p[s, a] == 1.0)
                continue
            ph = counts[s, a] / N[s, a]
            np.testing.assert_allclose(p_hat[s, a], ph, rtol=1e-6)
            wp = np.sqrt(hp.alpha_p) * np.sqrt(14 * ph * (1 - ph) / N[s, a] * L) + hp.alpha_p * 49 * L / (
                3 * max(1, N[s, a] - 1))
            np.testing.assert_allclose(width_p[s, a], wp, rtol=1e-5)
            r_hat = float(state.reward_mean[s, a])
            wr = hp.alpha_r * hp.r_max * np.sqrt(3.5 * L / N[s, a])
            np.testing.assert_allclose(r_tilde[s, a], min(hp.r_max, r_hat + wr), rtol=1e-5)


def test_plan_solves_the_current_plausible_set_and_starts_an_epoch():
    # Enough data for narrow intervals: weak alphas make the confidence set small but not trivial.
    hp = UCRL2HParams(alpha_r=0.01, alpha_p=0.001)
    stream = [(0, 1, 0.9, 1, False), (1, 1, 0.1, 2, False), (2, 0, 0.5, 0, False), (0, 0, 0.2, 0, False)] * 30
    state, _ = _feed([(s, a, r, s2, None) for s, a, r, s2, _ in stream], replan=False)
    state = state.replace(hparams=hp)
    planned = jax.jit(UCRL2.plan)(jax.random.key(0), state)
    assert bool(planned.evi_converged) and not bool(planned.plan_due)
    # Independent reference: scipy's LP solves each pair's inner problem max {p . u : lo <= p <= hi, sum p = 1} at
    # the plan's bias u (lo, hi from the closed-form widths, checked above), so Q_ref = r~ + LP(u).
    p_hat, width_p, r_tilde = (np.asarray(x, np.float64) for x in confidence_widths(state))
    u = np.asarray(planned.u, np.float64)
    lo, hi = np.maximum(p_hat - width_p, 0.0), np.minimum(p_hat + width_p, 1.0)
    Q_ref = np.zeros_like(r_tilde)
    for s in range(3):
        for a in range(2):
            lp = optimize.linprog(-u, A_eq=np.ones((1, 3)), b_eq=[1.0], bounds=list(zip(lo[s, a], hi[s, a])),
                                  method="highs")
            assert lp.status == 0
            Q_ref[s, a] = r_tilde[s, a] - lp.fun
    np.testing.assert_allclose(planned.Q, Q_ref, rtol=1e-5, atol=1e-5)
    # The span rule certifies u: EVI iterates T_tau = tau T + (1 - tau) I, so span(T u - u) <= evi_tol / tau, and
    # min_s (T u - u)(s) <= optimistic gain <= max_s (T u - u)(s) (Puterman Thm 8.5.5).
    gap = Q_ref.max(-1) - u
    assert gap.max() - gap.min() <= hp.evi_tol / hp.aperiodicity + 1e-5
    # The greedy action is an argmax of the independent Q (up to float32 ties).
    greedy = np.asarray(planned.Q).argmax(-1)
    assert np.all(Q_ref[np.arange(3), greedy] >= Q_ref.max(-1) - 1e-5)
    np.testing.assert_array_equal(planned.schedule.epoch_visits, 0)
    np.testing.assert_array_equal(planned.schedule.visits, state.schedule.visits)


def test_plan_is_a_no_op_for_a_member_that_did_not_ask():
    state, _ = _feed(STREAM)
    out = jax.jit(UCRL2.plan)(jax.random.key(0), state)
    jax.tree.map(np.testing.assert_array_equal, out.replace(hparams=state.hparams), state)


def test_check_hparams_and_setting():
    check_hparams(UCRL2.default_hparams)
    check_hparams(UCRL2HParams(alpha_p=jnp.linspace(0.1, 3.0, 5)))  # a grid
    with pytest.raises(ValueError, match="alpha_p"):
        check_hparams(UCRL2HParams(alpha_p=jnp.array([0.5, -1.0])))
    with pytest.raises(ValueError, match="policy_discount"):
        check_hparams(UCRL2HParams(policy_discount=1.0))
    with pytest.raises(ValueError, match="evi_max_iter"):
        check_hparams(UCRL2HParams(evi_max_iter=0))
    episodic = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=3)
    with pytest.raises(ValueError, match="continuous"):
        UCRL2.init(jax.random.key(0), spec_of(episodic, 10), UCRL2.default_hparams)
