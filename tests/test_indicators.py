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
from jaxmdp.experiment.members import member_mdp
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


@pytest.mark.nightly  # by default: test_indicators_banded.py's runner gains against dense float64 ones
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


@pytest.mark.nightly  # by default: test_runner.py's action indices against the one-hot policy
def test_gain_bounds_of_action_indices_are_those_of_the_one_hot_policy():
    # A deterministic policy given by its action indices is swept on the chosen actions' K successor slots only:
    # the same bounds (to float32 rounding of the reordered sums), certificate and sweeps as its one-hot [S, A]
    # policy on all A K slots, and policy_values agrees with the dense gain (GTH elimination) to 1e-6. Random sparse
    # MDPs (multichain, transient-heavy chains) and a periodic 3-cycle feeding an absorbing state.
    from jaxmdp import dynamic_programming as dp

    rng = np.random.default_rng(21)
    T = np.zeros((6, 2, 6))
    T[0, :, 1] = T[1, :, 2] = T[2, :, 0] = 1.0  # a periodic closed class
    T[3, :, 3] = 1.0  # an absorbing state
    T[4, 0, [0, 3, 5]] = [0.2, 0.3, 0.5]  # transient states feeding both
    T[4, 1, [4, 5]] = [0.5, 0.5]
    T[5, :, [4, 5]] = [[0.6, 0.6], [0.4, 0.4]]
    cases = [(jaxmdp.custom_mdp(T, R=rng.random((6, 2))), rng.integers(0, 2, 6))]
    randoms = [random_mdp(rng, S=9, A=3, sparsity=(0.08, 0.3)[trial % 2]) for trial in range(8)]
    # Stacked, so that they share one successor width (padded slots; one compilation instead of one per width).
    stack = jaxmdp.stack(randoms)
    assert len({m.max_successors for m in randoms}) > 1
    cases += [(member_mdp(stack, i), rng.integers(0, 3, 9)) for i in range(len(randoms))]
    bounds = jax.jit(lambda m, pi: dp.successor_gain_bounds(m, pi, max_sweeps=256))
    values = jax.jit(lambda m, pi: indicators.policy_values(m, pi, indicators.ITERATIVE_GAIN_SWEEPS))
    for mdp, actions in cases:
        actions = jnp.asarray(actions, jnp.int32)
        one_hot = jax.nn.one_hot(actions, mdp.n_actions, dtype=jnp.float32)
        dense = np.asarray(dp.gain_vector(mdp, one_hot))
        b, ref = bounds(mdp, actions), bounds(mdp, one_hot)
        assert bool(b.certified) == bool(ref.certified) and int(b.sweeps) == int(ref.sweeps)
        np.testing.assert_allclose(b.lower, ref.lower, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(b.upper, ref.upper, rtol=1e-6, atol=1e-7)
        slack = 5e-7 * (1 + np.abs(dense))
        assert np.all(np.asarray(b.lower) <= dense + slack) and np.all(dense <= np.asarray(b.upper) + slack)
        np.testing.assert_allclose(values(mdp, actions), dense, rtol=5e-7, atol=5e-7)
        np.testing.assert_allclose(values(mdp, actions), values(mdp, one_hot), rtol=5e-7, atol=5e-7)


def test_refinement_certifies_a_transient_state_that_lingers_between_two_classes():
    # Classes of gain 0 and 1, and a transient state that stays with probability 0.4 and leaves to either class with
    # 0.3 (gain 1/2, closed form): its bounds close only through the refinement L <- max(L, P L), by a factor 0.4 a
    # pass, which stops at its fixed point instead of running a fixed count; the bounds contain the gains and meet.
    from jaxmdp import dynamic_programming as dp

    T = np.zeros((3, 1, 3))
    T[0, 0, 0] = T[2, 0, 2] = 1.0
    T[1, 0, [0, 1, 2]] = [0.3, 0.4, 0.3]
    chain = jaxmdp.custom_mdp(T, R=np.array([[0.0], [0.3], [1.0]]))
    b = dp.successor_gain_bounds(chain, jnp.ones((3, 1)), max_sweeps=256)
    assert bool(b.certified)
    assert np.all(np.asarray(b.lower) <= np.array([0.0, 0.5, 1.0]) + 1e-7)
    assert np.all(np.array([0.0, 0.5, 1.0]) <= np.asarray(b.upper) + 1e-7)
    np.testing.assert_allclose(b.lower, [0.0, 0.5, 1.0], atol=1e-6)
    np.testing.assert_allclose(b.upper, [0.0, 0.5, 1.0], atol=1e-6)
    np.testing.assert_array_equal(dp.successor_gain_bounds(chain, jnp.zeros((3,), jnp.int32)).lower, b.lower)


def test_slowly_mixing_chain_falls_back_to_the_dense_gain():
    # A lazy 2-cycle with switching probability 1e-4 cannot be certified in 128 sweeps; the dense gain is used.
    from jaxmdp import dynamic_programming as dp

    eps = 1e-4
    T = np.array([[[1 - eps, eps]], [[eps, 1 - eps]]])
    mdp = jaxmdp.custom_mdp(T, R=np.array([[0.0], [1.0]]))
    pi = jnp.ones((2, 1))
    assert not bool(dp.successor_gain_bounds(mdp, pi, max_sweeps=128).certified)
    np.testing.assert_allclose(indicators.policy_values(mdp, pi, 128), [0.5, 0.5], rtol=1e-6)


def _lazy_two_cycle(eps: float) -> jaxmdp.MDP:
    T = np.array([[[1 - eps, eps]], [[eps, 1 - eps]]])
    return jaxmdp.custom_mdp(T, R=np.array([[0.0], [1.0]]))


def test_giving_up_early_stops_on_a_slow_chain_and_keeps_every_certificate():
    # The bounds' gap on a lazy 2-cycle shrinks by 1 - eps a sweep (tau = 1/2) from about 5e5 tolerances: with eps =
    # 1e-4 it would need about 1.3e5 sweeps, so giving up stops at the first refresh (32 sweeps) instead of 128;
    # with eps = 0.13 it certifies at the fourth refresh (128 sweeps; 101 needed), and giving up changes nothing.
    # Random sparse MDPs: wherever the plain bounds certify, the same bounds and sweeps.
    from jaxmdp import dynamic_programming as dp

    pi = jnp.ones((2, 1))
    plain = jax.jit(lambda m, p: dp.successor_gain_bounds(m, p, max_sweeps=128))
    early = jax.jit(lambda m, p: dp.successor_gain_bounds(m, p, max_sweeps=128,
                                                          give_up=indicators.ITERATIVE_GAIN_GIVE_UP))
    slow = _lazy_two_cycle(1e-4)
    assert (int(plain(slow, pi).sweeps), int(early(slow, pi).sweeps)) == (128, 32)
    assert not bool(early(slow, pi).certified)
    # Given up, the exact gain instead.
    np.testing.assert_allclose(indicators.policy_values(slow, pi, 128, give_up=indicators.ITERATIVE_GAIN_GIVE_UP),
                               [0.5, 0.5], rtol=1e-6)
    rng = np.random.default_rng(8)
    cases = [(_lazy_two_cycle(0.13), pi)]
    cases += [(random_mdp(rng, S=7, A=3, sparsity=(0.08, 0.3, 0.6)[t % 3]), jnp.asarray(rng.dirichlet(np.ones(3), 7),
                                                                                      jnp.float32)) for t in range(6)]
    late = 0
    for mdp, p in cases:
        a, b = plain(mdp, p), early(mdp, p)
        assert bool(a.certified) and bool(b.certified) and int(a.sweeps) == int(b.sweeps)
        np.testing.assert_array_equal(a.lower, b.lower)
        np.testing.assert_array_equal(a.upper, b.upper)
        late += int(a.sweeps) == 128
    assert late >= 1


@pytest.mark.parametrize("give_up", [0.0, -1.0, float("nan")])
def test_giving_up_refuses_a_factor_that_is_not_positive(give_up):
    from jaxmdp import dynamic_programming as dp

    with pytest.raises(ValueError, match="give_up must be positive"):
        dp.successor_gain_bounds(_lazy_two_cycle(0.5), jnp.ones((2, 1)), give_up=give_up)


def test_the_runner_hands_its_give_up_to_the_bounds(monkeypatch):
    # The runner's member-by-member evaluation reads ITERATIVE_GAIN_GIVE_UP when it is traced: a factor that the
    # bounds refuse surfaces there (giving up changes costs only, not the gains, so this is how it shows).
    from jaxmdp.experiment import runner

    stacked = jaxmdp.stack([_lazy_two_cycle(0.5)]).strip()
    args = (stacked, jnp.zeros((1,), jnp.int32), jnp.zeros((1, 2), jnp.int32), jnp.ones((1,), bool),
            jnp.zeros((1, 2), jnp.float32))
    evaluate = lambda: jax.jit(lambda *a: runner._evaluate_changed(*a))(*args)  # noqa: E731 (traced anew)
    np.testing.assert_allclose(evaluate(), [[0.5, 0.5]], rtol=1e-6)
    monkeypatch.setattr(indicators, "ITERATIVE_GAIN_GIVE_UP", 0.0)
    with pytest.raises(ValueError, match="give_up must be positive"):
        evaluate()
