"""The span of the optimal bias against brute force (every deterministic policy's gain and bias by numpy float64
solves, kept when they satisfy the optimality equation), a closed form, and its invariances."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import hardness
import jaxmdp
from hardness.bias_span import average_reward_solution

from average_reward_brute import mdp, optimality_solutions, random_unichain


def small(T, R):
    """A hand-made MDP padded to 3 states, 2 actions and 3 successors: one compilation for all of them."""
    return jaxmdp.pad(mdp(T, R), 3, 2, 3)


def brute_span(T, R):
    """``sp(h*)`` from every optimality-equation solution of the enumeration, checking that they agree (the solution
    of a unichain MDP is unique up to a constant)."""
    sols = optimality_solutions(T, R)
    assert sols, "no deterministic policy satisfies the optimality equation"
    spans = [np.ptp(h) for _, h in sols]
    np.testing.assert_allclose(spans, spans[0], rtol=1e-9, atol=1e-12)
    return spans[0]


def random_cases(n_per_shape=3):
    rng = np.random.default_rng(59)
    cases = []
    for S in (2, 3, 4):
        for A in (2, 3):
            for sparsity in (1.0, 0.4):
                cases += [random_unichain(rng, S, A, sparsity) for _ in range(n_per_shape)]
    return cases


@pytest.fixture(scope="module")
def cases():
    return random_cases()


@pytest.fixture(scope="module")
def batch_values(cases):
    # One stacked batch (padded to 4 states, 3 actions), one compilation: padding is exercised by every member.
    batch = jaxmdp.stack([mdp(T, R) for T, R in cases])
    return jax.jit(jax.vmap(hardness.bias_span))(batch)


def test_matches_brute_force_on_random_unichain_mdps(cases, batch_values):
    assert bool(jnp.all(batch_values.converged))
    expected = np.asarray([brute_span(T, R) for T, R in cases])
    np.testing.assert_allclose(np.asarray(batch_values.value), expected, rtol=2e-4, atol=2e-5)


def test_single_call_equals_the_batch_and_padding_and_permutation_change_nothing(cases, batch_values):
    T, R = cases[-1]
    m = mdp(T, R)
    one = hardness.bias_span(m)
    padded = hardness.bias_span(jaxmdp.pad(m, m.n_states + 2, m.n_actions + 1, m.max_successors + 1))
    perm = np.random.default_rng(1).permutation(T.shape[0])
    permuted = hardness.bias_span(mdp(T[perm][:, :, perm], R[perm]))
    for r in (one, padded, permuted):
        assert bool(r.converged)
        np.testing.assert_allclose(float(r.value), float(batch_values.value[-1]), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("p, q, r0, r1", [(0.1, 0.3, 1.0, 0.0), (0.5, 0.5, 0.2, 0.9), (0.02, 0.9, 0.7, 0.6)])
def test_two_state_chain_closed_form(p, q, r0, r1):
    # One action: P = [[1-p, p], [q, 1-q]]; h(0) - h(1) = (r0 - r1) / (p + q) (from h + g = r + P h).
    T = np.array([[[1 - p, p]], [[q, 1 - q]]])
    R = np.array([[r0], [r1]])
    got = hardness.bias_span(small(T, R))
    np.testing.assert_allclose(float(got.value), abs(r0 - r1) / (p + q), rtol=1e-5)


def test_river_swim_matches_brute_force():
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, randomize_actions=False)
    T, R = np.asarray(m.T, np.float64), np.asarray(m.R, np.float64)
    got = hardness.bias_span(m)
    assert bool(got.converged)
    np.testing.assert_allclose(float(got.value), brute_span(T, R), rtol=2e-4)


def test_solution_satisfies_the_optimality_equation(cases):
    T, R = cases[-1]
    sol = jax.jit(average_reward_solution)(mdp(T, R))
    h = np.asarray(sol.bias, np.float64)
    g, _ = optimality_solutions(T, R)[0]
    np.testing.assert_allclose(float(sol.gain), g, rtol=1e-5)
    np.testing.assert_allclose((R + T @ h).max(1) - h - g, 0.0, atol=1e-5)


def test_gain_depending_on_the_start_is_not_certified():
    # Two absorbing states with rewards 0 and 1: no solution with a constant gain exists.
    T = np.zeros((3, 1, 3))
    T[0, 0, 0] = T[1, 0, 1] = 1.0
    T[2, 0] = [0.5, 0.5, 0.0]
    R = np.array([[0.0], [1.0], [0.5]])
    got = hardness.bias_span(small(T, R))
    assert not bool(got.converged) and float(got.value) == np.inf


def test_weakly_communicating_gives_a_certified_solution():
    # Two states, each with a reward-1 self-loop and a reward-0 move to the other: every h with |h0 - h1| <= 1
    # solves the equation (not unichain); the value is one solution's span.
    T = np.zeros((2, 2, 2))
    T[0, 0, 0] = T[0, 1, 1] = T[1, 0, 1] = T[1, 1, 0] = 1.0
    R = np.array([[1.0, 0.0], [1.0, 0.0]])
    got = hardness.bias_span(small(T, R))
    assert bool(got.converged) and 0.0 <= float(got.value) <= 1.0


def test_bad_input():
    m = mdp(*random_cases(1)[0])
    with pytest.raises(ValueError, match="continuous"):
        hardness.bias_span(jaxmdp.make("DeepSea", episodic=True, seed=0, size=4))
    with pytest.raises(ValueError, match="rtol"):
        hardness.bias_span(m, rtol=0.0)
    with pytest.raises(ValueError, match="max_iter"):
        hardness.bias_span(m, max_iter=0)
