"""Exact regret indicators against brute force in numpy (every deterministic policy enumerated) and hand-worked
numbers."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmdp
from jaxmdp.experiment import indicators
from conftest import random_mdp
from numpy_reference import finite_horizon_eval as np_finite_horizon_eval
from numpy_reference import gain_ergodic as np_gain
from numpy_reference import one_hot


@pytest.fixture(scope="module")
def episodic_case():
    rng = np.random.default_rng(3)
    mdp = random_mdp(rng, S=3, A=2, H=3)
    T, R, P0 = (np.asarray(x, np.float64) for x in (mdp.T, mdp.R, mdp.P0))
    H, S, A = 3, 3, 2
    # Brute force over all A^(S H) deterministic Markov policies: the optimal (minimising) policy maximises
    # (minimises) V_0(s) for every s at once, so per-state extremes are the optimal and worst values.
    values = np.array([np_finite_horizon_eval(T, R, one_hot(np.reshape(c, (H, S)), A), H)
                       for c in itertools.product(range(A), repeat=S * H)])
    return mdp, T, R, P0, values.max(0), values.min(0), rng


def test_episodic_constants_match_brute_force(episodic_case):
    mdp, T, R, P0, v_opt, v_min, _ = episodic_case
    c = indicators.indicator_constants(mdp)
    np.testing.assert_allclose(c.optimal_start_values, v_opt, rtol=1e-5)
    np.testing.assert_allclose(c.worst_start_values, v_min, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(c.optimal, P0 @ v_opt / 3, rtol=1e-5)
    np.testing.assert_allclose(c.worst, P0 @ v_min / 3, rtol=1e-5)
    v_rand = np_finite_horizon_eval(T, R, np.full((3, 3, 2), 0.5), 3)
    np.testing.assert_allclose(c.random, P0 @ v_rand / 3, rtol=1e-5)


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_episodic_instantaneous_matches_numpy(episodic_case, variant):
    mdp, T, R, P0, v_opt, v_min, rng = episodic_case
    consts = indicators.indicator_constants(mdp, variant)
    f = jax.jit(lambda pi, s0: indicators.instantaneous(mdp, consts, pi, jnp.int32(0), s0, variant))
    for trial in range(4):
        pi = rng.dirichlet(np.ones(2), size=(3, 3))
        v_pi = np_finite_horizon_eval(T, R, pi, 3)
        for s0 in range(3):
            out = f(jnp.asarray(pi, jnp.float32), jnp.int32(s0))
            if variant == "paper":
                gap, span = P0 @ (v_opt - v_pi), P0 @ (v_opt - v_min)
            else:
                gap, span = v_opt[s0] - v_pi[s0], v_opt[s0] - v_min[s0]
            np.testing.assert_allclose(out.regret, gap / 3, rtol=1e-4, atol=1e-6)
            np.testing.assert_allclose(out.normalized_regret, gap / span, rtol=1e-4, atol=1e-6)
            np.testing.assert_allclose(out.expected_reward, P0 @ v_pi / 3, rtol=1e-5)


def test_episodic_optimal_policy_has_zero_regret(episodic_case):
    mdp = episodic_case[0]
    consts = indicators.indicator_constants(mdp)
    ref = jaxmdp.reference_values(mdp)
    out = indicators.instantaneous(mdp, consts, ref.optimal_policy, jnp.int32(0), jnp.int32(0))
    assert float(out.regret) == pytest.approx(0.0, abs=1e-6)
    out = indicators.instantaneous(mdp, consts, ref.worst_policy, jnp.int32(0), jnp.int32(0))
    assert float(out.normalized_regret) == pytest.approx(1.0, abs=1e-5)


@pytest.fixture(scope="module")
def continuous_case():
    rng = np.random.default_rng(5)
    mdp = random_mdp(rng, S=4, A=2, sparsity=1.0)  # dense kernel: every policy is ergodic
    T, R = np.asarray(mdp.T, np.float64), np.asarray(mdp.R, np.float64)
    policies = [one_hot(c, 2) for c in itertools.product(range(2), repeat=4)]
    gains = np.array([np_gain(T, R, pi) for pi in policies])
    # The colosseum variant's rho* and rho^- by brute force: the gains of the deterministic policies whose
    # gamma = 0.99 discounted values are largest (smallest) in every state (a discounted MDP has a uniformly optimal
    # deterministic policy, so the elementwise extreme is attained by one of the 16).
    disc = np.array([np.linalg.solve(np.eye(4) - 0.99 * np.einsum("sa,sat->st", pi, T), (pi * R).sum(-1))
                     for pi in policies])
    best, worst = int(np.argmax(disc.sum(-1))), int(np.argmin(disc.sum(-1)))
    assert np.all(disc[best] >= disc.max(0) - 1e-9) and np.all(disc[worst] <= disc.min(0) + 1e-9)
    colosseum = (gains[best], gains[worst])
    return mdp, T, R, {"paper": (gains.max(), gains.min()), "colosseum": colosseum}, rng


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_continuous_instantaneous_matches_numpy(continuous_case, variant):
    mdp, T, R, references, rng = continuous_case
    g_opt, g_min = references[variant]  # independent references (numpy brute force), not the constants under test
    consts = indicators.indicator_constants(mdp, variant)
    np.testing.assert_allclose([consts.optimal, consts.worst], [g_opt, g_min], rtol=1e-5)
    f = jax.jit(lambda pi, s: indicators.instantaneous(mdp, consts, pi, s, jnp.int32(0), variant))
    for trial in range(4):
        pi = rng.dirichlet(np.ones(2), size=4) if trial else np.full((4, 2), 0.5)
        g = np_gain(T, R, pi)
        regret = max(g_opt - g, 0.0)
        if variant == "colosseum" and regret <= 1e-3:
            regret = 0.0
        for s in range(4):
            out = f(jnp.asarray(pi, jnp.float32), jnp.int32(s))
            np.testing.assert_allclose(out.expected_reward, g, rtol=1e-5)
            np.testing.assert_allclose(out.regret, regret, rtol=1e-4, atol=1e-6)
            np.testing.assert_allclose(out.normalized_regret, regret / (g_opt - g_min), rtol=1e-4, atol=1e-6)


def test_continuous_multichain_policy_uses_the_current_state():
    # Two states, "stay" (0) and "switch" (1); state 1 pays 1. Staying everywhere has gain 0 from state 0 and 1
    # from state 1; the optimal gain is 1.
    T = np.zeros((2, 2, 2))
    T[0, 0, 0] = T[1, 0, 1] = T[0, 1, 1] = T[1, 1, 0] = 1.0
    mdp = jaxmdp.custom_mdp(T, R=np.array([[0.0, 0.0], [1.0, 1.0]]))
    consts = indicators.indicator_constants(mdp)
    stay = jnp.asarray([[1.0, 0.0], [1.0, 0.0]])
    from0 = indicators.instantaneous(mdp, consts, stay, jnp.int32(0), jnp.int32(0))
    from1 = indicators.instantaneous(mdp, consts, stay, jnp.int32(1), jnp.int32(0))
    np.testing.assert_allclose([from0.regret, from0.expected_reward, from0.normalized_regret], [1, 0, 1], atol=1e-6)
    np.testing.assert_allclose([from1.regret, from1.expected_reward, from1.normalized_regret], [0, 1, 0], atol=1e-6)


def test_degenerate_normaliser_gives_zero():
    # Every policy is optimal (constant reward): the normalised regret is 0, not 0/0.
    mdp = jaxmdp.custom_mdp(np.full((2, 2, 2), 0.5), R=np.full((2, 2), 0.3), H=2)
    consts = indicators.indicator_constants(mdp)
    out = indicators.instantaneous(mdp, consts, jnp.full((2, 2, 2), 0.5), jnp.int32(0), jnp.int32(0))
    assert float(out.normalized_regret) == 0.0 and float(out.regret) == pytest.approx(0.0, abs=1e-7)


def test_baseline_columns_hand_worked():
    cols = indicators.baseline_columns(np.array([100.0]), 0.9, 0.1, 0.3)
    expected = {
        "random_cumulative_regret": 60.0,
        "random_cumulative_expected_reward": 30.0,
        "random_normalized_cumulative_regret": 75.0,
        "random_normalized_cumulative_expected_reward": 25.0,
        "worst_cumulative_regret": 80.0,
        "worst_cumulative_expected_reward": 10.0,
        "worst_normalized_cumulative_regret": 100.0,
        "worst_normalized_cumulative_expected_reward": 0.0,
        "optimal_cumulative_expected_reward": 90.0,
        "optimal_normalized_cumulative_expected_reward": 100.0,
    }
    assert set(cols) == set(expected)
    for k, v in expected.items():
        np.testing.assert_allclose(cols[k], v, rtol=1e-12, err_msg=k)
    np.testing.assert_allclose(indicators.normalized_reward(50.0, 100.0, 0.9, 0.1), 50.0, rtol=1e-12)
    assert set(indicators.CSV_COLUMNS) == {"steps", "steps_per_second", "normalized_cumulative_reward",
                                           "normalized_cumulative_expected_reward", *indicators.AGENT_COLUMNS, *cols}


def test_bad_variant():
    mdp = jaxmdp.custom_mdp(np.full((2, 2, 2), 0.5), R=np.eye(2))
    with pytest.raises(ValueError, match="variant"):
        indicators.indicator_constants(mdp, "gym")


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_stacked_constants_match_each_mdp_alone(variant):
    # The runner's constants of a padded stack (lax.map) equal those of every member computed alone, and the padded
    # members converge in as many sweeps as alone (padded states are left out of optimal_gain's stopping rule; with
    # them the span never fell below tol and every padded member ran all 200 000 sweeps).
    from jaxmdp import dynamic_programming as dp
    from jaxmdp.experiment import runner

    rng = np.random.default_rng(11)
    mdps = [random_mdp(rng, S=S, A=A, sparsity=0.4) for S, A in ((3, 2), (6, 3))]
    stacked = runner._constants_program(variant)(jaxmdp.stack(mdps).strip(), jnp.arange(len(mdps)))
    for i, m in enumerate(mdps):
        alone = jax.jit(indicators.indicator_constants, static_argnums=1)(m, variant)
        for name in ("optimal", "worst", "random"):
            np.testing.assert_allclose(getattr(stacked, name)[i], getattr(alone, name), rtol=1e-6, atol=1e-7)
        S = m.n_states
        np.testing.assert_allclose(stacked.optimal_start_values[i, :S], alone.optimal_start_values, rtol=1e-6,
                                   atol=1e-7)
    if variant == "paper":
        sweeps = jax.jit(lambda m: dp.optimal_gain(m).iterations)
        assert int(sweeps(jax.tree.map(lambda x: x[0], jaxmdp.stack(mdps).strip()))) == int(sweeps(mdps[0]))


def test_successor_gain_bounds_match_the_dense_gain():
    # Random sparse MDPs (many multichain and transient-heavy policy chains), deterministic and stochastic policies:
    # the certified bounds contain the dense gain (GTH elimination) and their midpoint agrees with it to 1e-6.
    from jaxmdp import dynamic_programming as dp

    rng = np.random.default_rng(8)
    bounds = jax.jit(dp.successor_gain_bounds)
    values = jax.jit(lambda m, pi: indicators.policy_values(m, pi, indicators.ITERATIVE_GAIN_SWEEPS))
    certified = 0
    for trial in range(12):
        mdp = random_mdp(rng, S=7, A=3, sparsity=(0.08, 0.3, 0.6)[trial % 3])
        pi = np.eye(3)[rng.integers(0, 3, 7)] if trial % 2 else rng.dirichlet(np.ones(3), 7)
        pi = jnp.asarray(pi, jnp.float32)
        dense = np.asarray(dp.gain_vector(mdp, pi))
        b = bounds(mdp, pi)
        assert bool(b.certified)
        slack = 5e-7 * (1 + np.abs(dense))
        assert np.all(np.asarray(b.lower) <= dense + slack) and np.all(dense <= np.asarray(b.upper) + slack)
        np.testing.assert_allclose((b.lower + b.upper) / 2, dense, rtol=5e-7, atol=5e-7)
        np.testing.assert_allclose(values(mdp, pi), dense, rtol=5e-7, atol=5e-7)
        certified += int(b.sweeps) <= indicators.ITERATIVE_GAIN_SWEEPS
    assert certified >= 6
    # Two classes with gains 0 and 1 and a transient state between them (gain 1/2): exact bounds, no dense work.
    T = np.zeros((3, 1, 3))
    T[0, 0, 0] = T[2, 0, 2] = 1.0
    T[1, 0, [0, 2]] = 0.5
    chain = jaxmdp.custom_mdp(T, R=np.array([[0.0], [0.3], [1.0]]))
    b = bounds(chain, jnp.ones((3, 1)))
    assert bool(b.certified)
    np.testing.assert_allclose(b.lower, [0.0, 0.5, 1.0], atol=1e-6)
    np.testing.assert_allclose(b.upper, [0.0, 0.5, 1.0], atol=1e-6)


def test_warm_started_gain_bounds_certify_the_dense_gain_from_any_start():
    # d_0 = r + (P - I) h has P* d_0 = g for every h: from a zero, a random, a large and a reused start, on random
    # sparse MDPs (multichain and transient-heavy policy chains), a periodic 3-cycle and a multichain chain, the
    # bounds contain the dense gain (GTH elimination), and certified midpoints agree with it to 1e-6.
    from jaxmdp import dynamic_programming as dp

    rng = np.random.default_rng(21)
    bounds = jax.jit(lambda m, pi, h: dp.successor_gain_bounds(m, pi, bias=h, max_sweeps=256))
    warm = jax.jit(indicators.warm_gain_values)
    T = np.zeros((6, 1, 6))
    T[0, 0, 1] = T[1, 0, 2] = T[2, 0, 0] = 1.0  # a periodic closed class
    T[3, 0, 3] = 1.0  # an absorbing state
    T[4, 0, [0, 3, 5]] = [0.2, 0.3, 0.5]  # transient states feeding both
    T[5, 0, [4, 5]] = [0.6, 0.4]
    periodic = jaxmdp.custom_mdp(T, R=rng.random((6, 1)))
    cases = [(periodic, jnp.ones((6, 1)))]
    for trial in range(8):
        mdp = random_mdp(rng, S=9, A=3, sparsity=(0.08, 0.3)[trial % 2])
        pi = np.eye(3)[rng.integers(0, 3, 9)] if trial % 2 else rng.dirichlet(np.ones(3), 9)
        cases.append((mdp, jnp.asarray(pi, jnp.float32)))
    for mdp, pi in cases:
        S = mdp.n_states
        dense = np.asarray(dp.gain_vector(mdp, pi))
        cold = bounds(mdp, pi, jnp.zeros(S))
        starts = {"zero": jnp.zeros(S), "random": jnp.asarray(rng.normal(size=S) * 3, jnp.float32),
                  "large": jnp.asarray(rng.normal(size=S) * 1e4, jnp.float32), "reused": cold.bias}
        for name, h in starts.items():
            b = bounds(mdp, pi, h)
            slack = 5e-7 * (1 + np.abs(dense))
            assert np.all(np.asarray(b.lower) <= dense + slack) and np.all(dense <= np.asarray(b.upper) + slack)
            # A zero or reused start certifies (in 256 sweeps); a random one may take longer, and a 1e4-scale one
            # leaves d_0 ~ 1e4 (rounding 1e-3) in float32.
            assert bool(b.certified) or name in ("random", "large")
            if bool(b.certified):
                np.testing.assert_allclose((b.lower + b.upper) / 2, dense, rtol=5e-7, atol=5e-7)
            values, bias = warm(mdp, pi, h)
            np.testing.assert_allclose(values, dense, rtol=5e-7, atol=5e-7)
            scale = 1 + float(jnp.max(jnp.abs(h))) + float(jnp.max(jnp.abs(bias)))
            assert abs(float(jnp.mean(bias))) < 1e-5 * scale  # centred (to the rounding of the start's magnitude)
        # Restarting from its own bias estimate saves sweeps (certifies within the first 32 in 8 of these 9 cases).
        again = bounds(mdp, pi, cold.bias)
        assert int(again.sweeps) <= max(int(cold.sweeps) - 32, 32)


def test_warm_start_bias_estimate_is_the_bias_on_a_unichain():
    # On an ergodic chain the returned estimate solves r + (P - I) H = g up to the certified tolerance, i.e. it is the
    # bias (up to a constant): compared with numpy's least-squares solution of (I - P) h = r - g, centred alike.
    from jaxmdp import dynamic_programming as dp

    rng = np.random.default_rng(4)
    mdp = random_mdp(rng, S=8, A=2, sparsity=0.6)
    pi = jnp.asarray(rng.dirichlet(np.ones(2), 8), jnp.float32)
    b = dp.successor_gain_bounds(mdp, pi, bias=jnp.zeros(8), max_sweeps=512)
    assert bool(b.certified)
    P = np.einsum("sa,sat->st", np.asarray(pi, np.float64), np.asarray(mdp.T, np.float64))
    r = np.sum(np.asarray(pi, np.float64) * np.asarray(mdp.R, np.float64), -1)
    mu = np.linalg.lstsq(np.vstack([(np.eye(8) - P).T, np.ones(8)]), np.r_[np.zeros(8), 1.0], rcond=None)[0]
    h = np.linalg.lstsq(np.eye(8) - P, r - mu @ r, rcond=None)[0]
    np.testing.assert_allclose(np.asarray(b.bias), h - h.mean(), atol=1e-3)


def test_slowly_mixing_chain_falls_back_to_the_dense_gain():
    # A lazy 2-cycle with switching probability 1e-4 cannot be certified in 128 sweeps; the dense gain is used.
    from jaxmdp import dynamic_programming as dp

    eps = 1e-4
    T = np.array([[[1 - eps, eps]], [[eps, 1 - eps]]])
    mdp = jaxmdp.custom_mdp(T, R=np.array([[0.0], [1.0]]))
    pi = jnp.ones((2, 1))
    assert not bool(dp.successor_gain_bounds(mdp, pi, max_sweeps=128).certified)
    np.testing.assert_allclose(indicators.policy_values(mdp, pi, 128), [0.5, 0.5], rtol=1e-6)
