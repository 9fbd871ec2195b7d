"""Mixing time and distribution mismatch coefficient against brute force (numpy float64 matrix powers, series,
trajectory enumeration) and hand-worked chains."""

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import hardness
import jaxmdp
from hardness.mixing import chain_mixing_time

from conftest import random_mdp


def cesaro64(P: np.ndarray) -> np.ndarray:
    """The Cesàro limit ``P*`` in float64: ``2^40`` lazy steps by renormalised squaring, checked against its defining
    identities ``P* P = P P* = P*`` and ``P* P* = P*``."""
    M = 0.5 * (np.eye(P.shape[0]) + P)
    for _ in range(40):
        M = M @ M
        M /= M.sum(1, keepdims=True)
    for other in (M @ P, P @ M, M @ M):
        np.testing.assert_allclose(other, M, atol=1e-9)
    return M


def brute_mixing_time(P: np.ndarray, eps: float, t_max: int = 10_000) -> float:
    """``min t`` with ``max_s TV(P^t(s,.), P*(s,.)) <= eps`` by explicit powers (float64)."""
    S = P.shape[0]
    Pstar = cesaro64(P)
    M = np.eye(S)
    for t in range(t_max):
        if 0.5 * np.abs(M - Pstar).sum(1).max() <= eps:
            return float(t)
        M = M @ P
    return np.inf


def random_chain(rng, S, sparsity=0.6):
    P = rng.random((S, S)) * (rng.random((S, S)) < sparsity)
    P[np.arange(S), rng.integers(0, S, S)] += 0.05
    return P / P.sum(1, keepdims=True)


@pytest.mark.parametrize("p, q", [(0.1, 0.3), (0.02, 0.05), (0.5, 0.5), (0.9, 0.8)])
@pytest.mark.parametrize("eps", [0.25, 0.1, 0.01])
def test_two_state_chain_closed_form(p, q, eps):
    # P = [[1-p, p], [q, 1-q]]: P^t(s,.) - pi = (1-p-q)^t (e_s - pi), so d(t) = max(p, q)/(p+q) |1-p-q|^t and
    # t_mix = min t >= 0 with that <= eps.
    P = jnp.asarray([[1 - p, p], [q, 1 - q]], jnp.float32)
    lam, c = abs(1 - p - q), max(p, q) / (p + q)
    expected = next(t for t in range(10_000) if c * lam**t <= eps)
    r = chain_mixing_time(P, eps)
    assert bool(r.converged) and float(r.value) == expected


def test_random_chains_match_matrix_powers():
    rng = np.random.default_rng(0)
    for S in (2, 3, 5, 8):
        for _ in range(4):
            P = random_chain(rng, S)
            for eps in (0.25, 0.05):
                got = float(chain_mixing_time(jnp.asarray(P, jnp.float32), eps).value)
                assert got == brute_mixing_time(P, eps), (S, eps)


def test_multichain_uses_each_start_limit():
    # Two closed classes {0,1} and {2} and a transient state 3 that splits between them: each start converges to its
    # own limit, so the chain mixes (the distance to a single stationary distribution would stay large).
    P = np.array([[0.6, 0.4, 0, 0], [0.3, 0.7, 0, 0], [0, 0, 1, 0], [0.2, 0, 0.5, 0.3]])
    got = float(chain_mixing_time(jnp.asarray(P, jnp.float32), 0.1).value)
    assert got == brute_mixing_time(P, 0.1) and np.isfinite(got)


def test_periodic_chain_is_infinite_and_lazy_is_finite():
    cycle = np.roll(np.eye(4), 1, axis=1)  # deterministic 4-cycle: d(t) = 3/4 for every t
    r = chain_mixing_time(jnp.asarray(cycle, jnp.float32), 0.25, max_doublings=12)
    assert not bool(r.converged) and np.isinf(float(r.value))
    lazy = 0.5 * (np.eye(4) + cycle)  # d(1) = 1/2, d(2) = 1/4 exactly (eps = 0.3 stays clear of that tie)
    r = chain_mixing_time(jnp.asarray(lazy, jnp.float32), 0.3)
    assert float(r.value) == brute_mixing_time(lazy, 0.3) == 2.0
    assert float(chain_mixing_time(jnp.asarray(cycle, jnp.float32), 0.8).value) == 0.0  # d(0) = 3/4 <= 0.8


def test_mixing_time_of_mdp_policy_and_default_optimal():
    rng = np.random.default_rng(1)
    m = random_mdp(rng, S=5, A=3)
    pi = rng.dirichlet(np.ones(3), size=5).astype(np.float32)
    P = np.einsum("sa,sat->st", pi.astype(np.float64), np.asarray(m.T, np.float64))
    assert float(hardness.mixing_time(m, jnp.asarray(pi)).value) == brute_mixing_time(P, 0.25)
    pi_opt = np.asarray(jaxmdp.reference_values(m).optimal_policy, np.float64)
    P_opt = np.einsum("sa,sat->st", pi_opt, np.asarray(m.T, np.float64))
    assert float(hardness.mixing_time(m).value) == brute_mixing_time(P_opt, 0.25)
    lazy = float(hardness.mixing_time(m, jnp.asarray(pi), lazy=True).value)
    assert lazy == brute_mixing_time(0.5 * (np.eye(5) + P), 0.25)


def test_mixing_time_vmaps_over_padded_batch():
    rng = np.random.default_rng(2)
    ms = [random_mdp(rng, S=4, A=2), random_mdp(rng, S=6, A=3)]
    batch = jaxmdp.stack(ms)
    got = jax.vmap(lambda m: hardness.mixing_time(m).value)(batch)
    np.testing.assert_array_equal(np.asarray(got), [float(hardness.mixing_time(m).value) for m in ms])


def test_mixing_time_bad_input():
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)
    with pytest.raises(ValueError, match="eps"):
        hardness.mixing_time(m, eps=0.0)
    with pytest.raises(ValueError, match="policy"):
        hardness.mixing_time(m, jnp.ones((3, 2)) / 2)
    with pytest.raises(ValueError, match="continuous MDP"):
        hardness.mixing_time(jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4))


# ---------------------------------------------------------------------------------------------------------------
# Distribution mismatch
# ---------------------------------------------------------------------------------------------------------------


def brute_discounted_visitation(T, P0, pi, gamma, n_terms=3000):
    P = np.einsum("sa,sat->st", pi, T)
    d, x = np.zeros(len(P0)), P0.copy()
    for t in range(n_terms):
        d += (1 - gamma) * gamma**t * x
        x = x @ P
    return d


def brute_episodic_visitation(T, P0, pis, H):
    """In-episode average state distribution by enumerating every trajectory ``s_0 a_0 ... s_{H-1}``."""
    S, A, _ = T.shape
    d = np.zeros(S)
    for traj in itertools.product(range(S), range(A), repeat=H):
        states, actions = traj[0::2], traj[1::2]
        prob = P0[states[0]]
        for h in range(H):
            prob *= pis[h][states[h], actions[h]]
            if h + 1 < H:
                prob *= T[states[h], actions[h], states[h + 1]]
        for h in range(H):
            d[states[h]] += prob / H
    return d


def ratio(d, mu):
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(mu > 0, d / np.where(mu > 0, mu, 1), np.where(d > 0, np.inf, 0))
    return r.max()


def test_identical_policies_give_one():
    rng = np.random.default_rng(3)
    for m in (random_mdp(rng, S=5, A=2), random_mdp(rng, S=4, A=3, H=3)):
        pi = rng.dirichlet(np.ones(m.n_actions), size=m.n_states).astype(np.float32)
        for g in ([None, 0.9] if not m.episodic else [None]):
            r = hardness.distribution_mismatch(m, jnp.asarray(pi), jnp.asarray(pi), gamma=g)
            assert abs(float(r.value) - 1.0) < 1e-6


def test_discounted_mismatch_matches_series():
    rng = np.random.default_rng(4)
    m = random_mdp(rng, S=5, A=3)
    T, P0 = np.asarray(m.T, np.float64), np.asarray(m.P0, np.float64)
    pi = rng.dirichlet(np.ones(3), size=5)
    ref = rng.dirichlet(np.ones(3), size=5)
    mu = rng.dirichlet(np.ones(5))
    d = brute_discounted_visitation(T, P0, pi, 0.9)
    got = hardness.distribution_mismatch(m, jnp.asarray(pi, jnp.float32), jnp.asarray(mu, jnp.float32), gamma=0.9)
    np.testing.assert_allclose(float(got.value), ratio(d, mu), rtol=1e-5)
    d_ref = brute_discounted_visitation(T, P0, ref, 0.9)
    got = hardness.distribution_mismatch(m, jnp.asarray(pi, jnp.float32), jnp.asarray(ref, jnp.float32), gamma=0.9)
    np.testing.assert_allclose(float(got.value), ratio(d, d_ref), rtol=1e-5)


def test_long_run_mismatch_matches_powers():
    rng = np.random.default_rng(5)
    m = random_mdp(rng, S=6, A=2)
    T, P0 = np.asarray(m.T, np.float64), np.asarray(m.P0, np.float64)
    pi, ref = rng.dirichlet(np.ones(2), size=6), rng.dirichlet(np.ones(2), size=6)
    limit = lambda p: P0 @ cesaro64(np.einsum("sa,sat->st", p, T))  # noqa: E731
    got = hardness.distribution_mismatch(m, jnp.asarray(pi, jnp.float32), jnp.asarray(ref, jnp.float32))
    np.testing.assert_allclose(float(got.value), ratio(limit(pi), limit(ref)), rtol=1e-4)


def test_episodic_mismatch_matches_enumeration():
    rng = np.random.default_rng(6)
    m = random_mdp(rng, S=3, A=2, H=3)
    T, P0 = np.asarray(m.T, np.float64), np.asarray(m.P0, np.float64)
    pis = rng.dirichlet(np.ones(2), size=(3, 3))  # time-indexed
    ref = rng.dirichlet(np.ones(2), size=3)  # stationary
    d, d_ref = brute_episodic_visitation(T, P0, pis, 3), brute_episodic_visitation(T, P0, [ref] * 3, 3)
    got = hardness.distribution_mismatch(m, jnp.asarray(pis, jnp.float32), jnp.asarray(ref, jnp.float32))
    np.testing.assert_allclose(float(got.value), ratio(d, d_ref), rtol=1e-5)
    mu = rng.dirichlet(np.ones(3))
    got = hardness.distribution_mismatch(m, jnp.asarray(pis, jnp.float32), jnp.asarray(mu, jnp.float32))
    np.testing.assert_allclose(float(got.value), ratio(d, mu), rtol=1e-5)


@pytest.mark.parametrize("size", [6, 24])
def test_deep_sea_optimal_against_random_is_two_to_the_depth(size):
    # The optimal policy walks the diagonal; the uniform policy is on the diagonal's h-th cell with probability 2^-h
    # and both spend 1/H of the episode at each depth, so the ratio is 2^(H-1) at the deepest diagonal cell (size 24:
    # a mass of 2^-23 relative to the largest, which must not be mistaken for round-off).
    m = jaxmdp.make("DeepSea", episodic=True, seed=0, size=size)
    uniform = jnp.full((m.n_states, m.n_actions), 0.5)
    assert float(hardness.distribution_mismatch(m, None, uniform).value) == 2.0 ** (size - 1)


def test_uncovered_state_gives_inf():
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)
    mu = jnp.asarray([1.0, 0, 0, 0])
    r = hardness.distribution_mismatch(m, None, mu)  # the optimal chain settles at the far end, which mu misses
    assert bool(r.converged) and np.isinf(float(r.value))


def test_mismatch_bad_input():
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)
    with pytest.raises(ValueError, match="reference"):
        hardness.distribution_mismatch(m, None, jnp.ones(3) / 3)
    with pytest.raises(ValueError, match="policy"):
        hardness.distribution_mismatch(m, jnp.ones((4, 3)) / 3, jnp.ones(4) / 4)
    with pytest.raises(ValueError, match="gamma"):
        hardness.distribution_mismatch(m, None, jnp.ones(4) / 4, gamma=1.0)
    e = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4)
    with pytest.raises(ValueError, match="gamma"):
        hardness.distribution_mismatch(e, None, jnp.ones(4) / 4, gamma=0.9)
