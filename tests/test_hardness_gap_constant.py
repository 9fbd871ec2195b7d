"""The Burnetas-Katehakis gap constant against brute force: the optimality equation's solution from every
deterministic policy (numpy float64), the KL projection by scipy's constrained minimiser (primal), the Bernoulli
closed form of the projection; and its invariances."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import hardness
import jaxmdp
from hardness.gap_constant import kl_inf

from average_reward_brute import burnetas_katehakis, kl_projection, mdp, random_unichain


@pytest.fixture(scope="module")
def cases():
    rng = np.random.default_rng(97)
    out = []
    for S in (2, 3, 4):
        for A in (2, 3):
            out += [random_unichain(rng, S, A, sparsity) for sparsity in (1.0, 0.5, 0.5)]
    return out


@pytest.fixture(scope="module")
def batch(cases):
    return jaxmdp.stack([mdp(T, R) for T, R in cases])


@pytest.fixture(scope="module")
def kl_values(batch):
    return jax.jit(jax.vmap(hardness.gap_constant))(batch)


@pytest.mark.parametrize("p1, mu", [(0.3, 0.6), (0.05, 0.5), (0.6, 0.61), (0.01, 0.99)])
def test_kl_inf_bernoulli_closed_form(p1, mu):
    # Two points with values 0 and 1: the projection moves q(1) up to mu exactly, K = kl(p1, mu).
    expected = (1 - p1) * np.log((1 - p1) / (1 - mu)) + p1 * np.log(p1 / mu)
    got = jax.jit(kl_inf)(jnp.asarray([1 - p1, p1]), jnp.asarray([0.0, 1.0]), jnp.asarray(mu), jnp.asarray(1.0))
    np.testing.assert_allclose(float(got), expected, rtol=1e-5)


def test_kl_inf_matches_the_primal_minimum():
    rng = np.random.default_rng(3)
    rows, expected = [], []
    for _ in range(40):
        k = 5
        p = rng.random(k) * (rng.random(k) < 0.7)
        p[rng.integers(k)] += 0.2
        p /= p.sum()
        x = rng.normal(size=k)
        allowed = (p > 0) if rng.random() < 0.5 else np.ones(k, bool)  # both support conventions
        upper = x[allowed].max()
        mu = p @ x + rng.uniform(0.05, 1.0) * (upper - p @ x) if rng.random() < 0.9 else upper + 0.1
        rows.append((p, x, mu, upper))
        expected.append(kl_projection(p, x, mu, allowed))
    p, x, mu, upper = (jnp.asarray(np.asarray(c), jnp.float32) for c in zip(*rows))
    got = np.asarray(jax.jit(jax.vmap(kl_inf))(p, x, mu, upper))
    expected = np.asarray(expected)
    assert np.array_equal(np.isinf(got), np.isinf(expected))
    fin = np.isfinite(expected)
    np.testing.assert_allclose(got[fin], expected[fin], rtol=2e-4, atol=1e-6)


def test_kl_inf_reached_or_out_of_reach():
    f = jax.jit(kl_inf)
    p, x = jnp.asarray([0.5, 0.5]), jnp.asarray([0.0, 1.0])
    assert float(f(p, x, jnp.asarray(0.4), jnp.asarray(1.0))) == 0.0  # p already passes the threshold
    assert float(f(p, x, jnp.asarray(1.0), jnp.asarray(1.0))) == np.inf  # no law on [0, 1] has mean > 1


@pytest.mark.parametrize("support", ["transition", "all"])
def test_matches_brute_force_on_random_unichain_mdps(cases, batch, kl_values, support):
    all_support = jax.vmap(lambda m: hardness.gap_constant(m, support="all"))
    got = kl_values if support == "transition" else jax.jit(all_support)(batch)
    assert bool(jnp.all(got.converged))
    expected = np.asarray([burnetas_katehakis(T, R, support)[0] for T, R in cases])
    np.testing.assert_allclose(np.asarray(got.value), expected, rtol=2e-3, atol=1e-5)


def test_reciprocal_form_matches_brute_force(cases, batch):
    got = jax.jit(jax.vmap(lambda m: hardness.gap_constant(m, form="reciprocal")))(batch)
    expected = np.asarray([burnetas_katehakis(T, R, "transition")[1] for T, R in cases])
    np.testing.assert_allclose(np.asarray(got.value), expected, rtol=2e-3)


def test_known_support_makes_a_deterministic_move_known():
    # State 0: action 0 stays with reward 1, action 1 stays with reward 0.5 (gap 0.5); state 1 (reward 2, transient)
    # returns to 0 with probability 0.5, so g* = 1, h*(0) = 0, h*(1) = 2. Under the known support action 1's law stays
    # the point mass on 0 and cannot pass mu = g* + h*(0) - 0.5 = 0.5: not critical, C = 0. A law that may reach
    # state 1 (support "all") needs q(1) >= 1/4: K = -log(3/4), C = 0.5 / log(4/3).
    T = np.zeros((2, 2, 2))
    T[0, :, 0] = 1.0
    T[1, :, :] = [0.5, 0.5]
    R = np.array([[1.0, 0.5], [2.0, 2.0]])
    m = mdp(T, R)
    known = hardness.gap_constant(m)
    free = hardness.gap_constant(m, support="all")
    assert bool(known.converged) and float(known.value) == 0.0
    assert bool(free.converged)
    np.testing.assert_allclose(float(free.value), 0.5 / np.log(4 / 3), rtol=1e-5)
    np.testing.assert_allclose(burnetas_katehakis(T, R, "all")[0], 0.5 / np.log(4 / 3), rtol=1e-6)


def test_single_call_equals_the_batch_and_padding_and_permutation_change_nothing(cases, kl_values):
    T, R = cases[-1]
    ref = kl_values.value[-1]
    m = mdp(T, R)
    perm = np.random.default_rng(5).permutation(T.shape[0])
    for other in (m, jaxmdp.pad(m, m.n_states + 2, m.n_actions + 1, m.max_successors + 1),
                  mdp(T[perm][:, :, perm], R[perm])):
        got = hardness.gap_constant(other)
        assert bool(got.converged)
        np.testing.assert_allclose(float(got.value), float(ref), rtol=1e-4)


def test_bad_input(cases):
    m = mdp(*cases[0])
    with pytest.raises(ValueError, match="form"):
        hardness.gap_constant(m, form="bk")
    with pytest.raises(ValueError, match="support"):
        hardness.gap_constant(m, support="known")
    with pytest.raises(ValueError, match="rtol"):
        hardness.gap_constant(m, rtol=2.0)
    with pytest.raises(ValueError, match="continuous"):
        hardness.gap_constant(jaxmdp.make("DeepSea", episodic=True, seed=0, size=4))
