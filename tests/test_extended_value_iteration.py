"""Extended value iteration: inner maximisation against an LP, gains against brute force and exact solvers."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import linprog

import agents.extended_value_iteration as evi
from agents.extended_value_iteration import (
    confidence_box,
    extended_value_iteration,
    optimistic_expectation,
    optimistic_kernel,
)
from jaxmdp import dynamic_programming as dp
from jaxmdp.dynamic_programming import relative_value_iteration

from conftest import compilations


@pytest.mark.parametrize("seed", range(6))
def test_inner_maximisation_matches_linprog(seed):
    rng = np.random.default_rng(seed)
    S, A = 7, 3
    p_hat = rng.dirichlet(np.full(S, 0.4), size=(S, A))
    width = rng.uniform(0.0, 0.4, size=(S, A, S)) * (rng.random((S, A, S)) < 0.8)
    mask = np.ones(S, bool)
    mask[-1] = seed % 2 == 0  # odd seeds: the last state is padding
    p_hat = np.where(mask, p_hat, 0.0)
    p_hat /= p_hat.sum(-1, keepdims=True)
    u = rng.normal(size=S)
    u[2] = u[4]  # a tie in u
    lo, hi = confidence_box(jnp.asarray(p_hat, jnp.float32), jnp.asarray(width, jnp.float32), jnp.asarray(mask))
    value = np.asarray(optimistic_expectation(lo, hi, jnp.asarray(u, jnp.float32)))
    kernel = np.asarray(optimistic_kernel(lo, hi, jnp.asarray(u, jnp.float32)))
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    for s in range(S):
        for a in range(A):
            res = linprog(-u, A_eq=np.ones((1, S)), b_eq=[1.0], bounds=list(zip(lo[s, a], hi[s, a])), method="highs")
            assert res.status == 0
            np.testing.assert_allclose(value[s, a], -res.fun, atol=2e-6)
            # The returned kernel is feasible and attains the optimum.
            p = kernel[s, a]
            np.testing.assert_allclose(p.sum(), 1.0, atol=1e-6)
            assert np.all(p >= lo[s, a] - 1e-7) and np.all(p <= hi[s, a] + 1e-7)
            np.testing.assert_allclose(p @ u, -res.fun, atol=2e-6)
            assert np.all(p[~mask] == 0.0)


def _box_vertices(lo, hi):
    """Vertices of {lo <= p <= hi, sum p = 1}: all coordinates but one at a bound, the free one in its box."""
    S = len(lo)
    out = []
    for j in range(S):
        others = [i for i in range(S) if i != j]
        for bits in itertools.product((0, 1), repeat=S - 1):
            p = np.empty(S)
            for i, b in zip(others, bits):
                p[i] = hi[i] if b else lo[i]
            p[j] = 1.0 - p[others].sum()
            if lo[j] - 1e-12 <= p[j] <= hi[j] + 1e-12:
                out.append(p)
    return np.unique(np.round(np.array(out), 12), axis=0)


def _brute_force_optimistic_gain(p_hat, width, r):
    """Best gain over deterministic policies of the finite MDP whose actions are (a, vertex of the box)."""
    S, A, _ = p_hat.shape
    lo = np.maximum(p_hat - width, 0.0)
    hi = np.minimum(p_hat + width, 1.0)
    choices = []  # per state: list of (reward, kernel row)
    for s in range(S):
        choices.append([(r[s, a], v) for a in range(A) for v in _box_vertices(lo[s, a], hi[s, a])])
    best = -np.inf
    for combo in itertools.product(*[range(len(c)) for c in choices]):
        P = np.array([choices[s][i][1] for s, i in enumerate(combo)])
        rew = np.array([choices[s][i][0] for s, i in enumerate(combo)])
        # Every kernel entry is positive (lo > 0), so the chain is irreducible: solve mu (I - P) = 0, sum mu = 1.
        M = np.vstack([(np.eye(S) - P).T, np.ones(S)])
        mu = np.linalg.lstsq(M, np.r_[np.zeros(S), 1.0], rcond=None)[0]
        best = max(best, mu @ rew)
    return best


@pytest.mark.parametrize("seed", range(3))
def test_evi_gain_matches_brute_force(seed):
    rng = np.random.default_rng(10 + seed)
    S, A = 3, 2
    p_hat = 0.15 + 0.55 * rng.dirichlet(np.ones(S), size=(S, A))
    p_hat /= p_hat.sum(-1, keepdims=True)
    width = rng.uniform(0.0, 0.12, size=(S, A, S))
    r = rng.uniform(0, 1, size=(S, A))
    res = extended_value_iteration(
        jnp.asarray(p_hat, jnp.float32),
        jnp.asarray(width, jnp.float32),
        jnp.asarray(r, jnp.float32),
        jnp.ones(S, bool),
        jnp.ones(A, bool),
        tol=1e-5,
    )
    assert bool(res.converged)
    expected = _brute_force_optimistic_gain(p_hat, width, r)
    assert float(res.gain_lower) <= expected + 1e-5 and expected - 1e-5 <= float(res.gain_upper)
    np.testing.assert_allclose(0.5 * (float(res.gain_lower) + float(res.gain_upper)), expected, atol=1e-5)


def test_evi_with_zero_widths_is_optimal_gain(rng=np.random.default_rng(5)):
    S, A = 8, 3
    T = rng.dirichlet(np.full(S, 0.3), size=(S, A))
    R = rng.uniform(0, 1, size=(S, A))
    ref = dp.optimal_gain(jnp.asarray(T, jnp.float32), rewards=jnp.asarray(R, jnp.float32), tol=1e-7)
    res = extended_value_iteration(
        jnp.asarray(T, jnp.float32), jnp.zeros((S, A, S)), jnp.asarray(R, jnp.float32), jnp.ones(S, bool),
        jnp.ones(A, bool), tol=1e-6,
    )
    assert bool(res.converged)
    np.testing.assert_allclose(float(res.gain_lower), float(ref.gain), atol=2e-6)
    np.testing.assert_allclose(float(res.gain_upper), float(ref.gain), atol=2e-6)
    # Its greedy policy is gain optimal in the true MDP.
    pi = dp.greedy(res.Q)
    gain = dp.gain_vector(jnp.asarray(T, jnp.float32), pi, jnp.asarray(R, jnp.float32))
    np.testing.assert_allclose(gain, float(ref.gain), atol=1e-5)


def test_evi_unconstrained_pairs_reach_the_best_reward():
    # Width 1 everywhere: every next-state distribution is plausible, so the optimistic gain is the largest reward.
    S, A = 4, 2
    r = jnp.array([[0.1, 0.2], [0.3, 0.7], [0.0, 0.5], [0.6, 0.4]])
    res = extended_value_iteration(jnp.full((S, A, S), 1 / S), jnp.ones((S, A, S)), r, jnp.ones(S, bool),
                                   jnp.ones(A, bool), tol=1e-6)
    np.testing.assert_allclose([res.gain_lower, res.gain_upper], [0.7, 0.7], atol=1e-6)
    assert int(jnp.argmax(res.Q[1])) == 1


def test_aperiodicity_transform_solves_periodic_chains():
    # Two states swapped by the only action, rewards 1 and 0: gain 1/2. Plain value iteration oscillates forever.
    P = jnp.array([[[0.0, 1.0]], [[1.0, 0.0]]])
    R = jnp.array([[1.0], [0.0]])
    kwargs = dict(state_mask=jnp.ones(2, bool), action_mask=jnp.ones(1, bool), tol=1e-6, max_iter=2_000)
    backup = lambda u: R + jnp.einsum("sat,t->sa", P, u)  # noqa: E731
    res = relative_value_iteration(backup, jnp.zeros(2), aperiodicity=0.5, **kwargs)
    assert bool(res.converged)
    np.testing.assert_allclose([res.gain_lower, res.gain_upper], [0.5, 0.5], atol=1e-6)
    # Bias: h(0) - h(1) = 1/2 (h = r - g + P h).
    np.testing.assert_allclose(res.u[0] - res.u[1], 0.5, atol=1e-5)
    plain = relative_value_iteration(backup, jnp.zeros(2), aperiodicity=1.0, **kwargs)
    assert not bool(plain.converged) and int(plain.iterations) == 2_000


def test_discounted_mode_matches_exact_solution(rng=np.random.default_rng(6)):
    S, A, gamma, tol = 6, 3, 0.9, 1e-6
    T = jnp.asarray(rng.dirichlet(np.full(S, 0.5), size=(S, A)), jnp.float32)
    R = jnp.asarray(rng.uniform(0, 1, size=(S, A)), jnp.float32)
    exact = dp.solve_discounted(T, gamma, rewards=R)
    backup = lambda u: R + gamma * jnp.einsum("sat,t->sa", T, u)  # noqa: E731
    res = relative_value_iteration(backup, jnp.zeros(S), jnp.ones(S, bool), jnp.ones(A, bool), discount=gamma,
                                   tol=tol)
    assert bool(res.converged)
    np.testing.assert_allclose(res.u, exact.V, atol=tol * gamma / (1 - gamma) + 1e-5)
    np.testing.assert_allclose(res.Q, exact.Q, atol=tol / (1 - gamma) + 1e-5)


def test_padded_states_and_actions_are_ignored():
    # The same MDP with one padded state (unreachable) and one padded action (very rewarding) has the same gain.
    rng = np.random.default_rng(7)
    S, A = 4, 2
    T = rng.dirichlet(np.full(S, 0.5), size=(S, A))
    R = rng.uniform(0, 1, size=(S, A))
    Tp = np.zeros((S + 1, A + 1, S + 1))
    Tp[:S, :A, :S] = T
    Tp[:S, A, :S] = T[:, 0]
    Tp[S, :, S] = 1.0
    Rp = np.full((S + 1, A + 1), 5.0)
    Rp[:S, :A] = R
    kw = dict(tol=1e-6)
    a = extended_value_iteration(jnp.asarray(T), jnp.full((S, A, S), 0.05), jnp.asarray(R), jnp.ones(S, bool),
                                 jnp.ones(A, bool), **kw)
    b = extended_value_iteration(jnp.asarray(Tp), jnp.full((S + 1, A + 1, S + 1), 0.05), jnp.asarray(Rp),
                                 jnp.arange(S + 1) < S, jnp.arange(A + 1) < A, **kw)
    np.testing.assert_allclose([b.gain_lower, b.gain_upper], [a.gain_lower, a.gain_upper], atol=1e-6)
    np.testing.assert_allclose(b.Q[:S, :A] - b.u[:S, None], a.Q - a.u[:, None], atol=1e-5)


# --- the sorted inner maximisation (S >= SORTED_FROM) against the dense product and an LP -------------------------


def _random_boxes(rng, S, A, n_padded=0):
    mask = np.arange(S) < S - n_padded
    p_hat = rng.dirichlet(np.full(S, 0.2), size=(S, A)) * mask
    p_hat /= p_hat.sum(-1, keepdims=True)
    width = rng.uniform(0.0, 0.05, size=(S, A, S)) * (rng.random((S, A, S)) < 0.7)
    lo, hi = confidence_box(jnp.asarray(p_hat, jnp.float32), jnp.asarray(width, jnp.float32), jnp.asarray(mask))
    return lo, hi, mask


def test_exclusive_running_sum_is_a_shifted_cumsum(rng=np.random.default_rng(7)):
    for S in (1, 31, 32, 33, 250):
        x = rng.uniform(size=(S, 5)).astype(np.float32)
        want = np.concatenate([np.zeros((1, 5)), np.cumsum(x.astype(np.float64), axis=0)[:-1]])
        np.testing.assert_allclose(evi._exclusive_running_sum(jnp.asarray(x)), want, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("seed", range(3))
def test_sorted_inner_maximisation_matches_dense_and_linprog(seed):
    rng = np.random.default_rng(seed)
    S, A = evi.SORTED_FROM + 13 * seed, 2
    lo, hi, mask = _random_boxes(rng, S, A, n_padded=seed)
    u = rng.normal(size=S).astype(np.float32)
    u[3] = u[7] = u[11]  # ties: lower index first
    u = jnp.asarray(u)
    sorted_extra = np.asarray(evi._extra_mass(lo, hi, u))
    np.testing.assert_allclose(sorted_extra, evi._dense_extra_mass(lo, hi, u), atol=2e-7)
    value = np.asarray(optimistic_expectation(lo, hi, u))
    lo64, hi64, u64 = (np.asarray(x, np.float64) for x in (lo, hi, u))
    for s, a in [(0, 0), (S // 2, 1), (S - 1 - seed, 0)]:
        res = linprog(-u64, A_eq=np.ones((1, S)), b_eq=[1.0], bounds=list(zip(lo64[s, a], hi64[s, a])), method="highs")
        assert res.status == 0
        np.testing.assert_allclose(value[s, a], -res.fun, atol=2e-6)


# --- boxes on each pair's slots (UCRL2's plan) against the dense boxes and an LP ---------------------------------


def _slot_boxes(rng, S, A, K, n_real, empty=0.3):
    """Boxes given on ``K`` slots per pair (distinct real states, some slots empty: box ``[0, c]``) and ``[0, c]`` at
    every other real state, and the same boxes written densely, entry by entry."""
    mask = np.arange(S) < n_real
    states = np.stack([rng.choice(n_real, K, replace=False) for _ in range(S * A)]).reshape(S, A, K)
    filled = rng.random((S, A, K)) > empty
    filled[0, 0] = False  # a pair with no observation: its box is [0, c] everywhere
    p = rng.random((S, A, K)) * filled
    p = p / np.maximum(p.sum(-1, keepdims=True), 1e-9)
    c = np.where(rng.random((S, A)) < 0.2, 1.0, rng.uniform(0.0, 0.2, (S, A)))
    c[0, 0] = 1.0
    w = np.where(filled, rng.uniform(0.0, 0.3, (S, A, K)), c[..., None])
    lo = np.where(filled, np.maximum(p - w, 0.0), 0.0)
    hi = np.where(filled, np.minimum(p + w, 1.0), c[..., None])
    dense_lo = np.zeros((S, A, S))
    dense_hi = np.where(mask, c[..., None], 0.0) * np.ones(S)
    for i, j, k in itertools.product(range(S), range(A), range(K)):
        dense_lo[i, j, states[i, j, k]], dense_hi[i, j, states[i, j, k]] = lo[i, j, k], hi[i, j, k]
    assert np.all(dense_lo.sum(-1) <= 1.0) and np.all(dense_hi.sum(-1) >= 1.0 - 1e-12)
    f32 = lambda x: jnp.asarray(x, jnp.float32)  # noqa: E731
    return (jnp.asarray(states, jnp.int32), f32(lo), f32(hi), f32(c), jnp.asarray(mask)), dense_lo, dense_hi


@pytest.mark.parametrize("S, K, n_real", [(7, 3, 5), (33, 5, 33), (230, 4, 200)])
def test_slot_boxes_inner_maximisation_matches_dense_and_linprog(S, K, n_real):
    rng = np.random.default_rng(S)
    A = 2
    slots, dense_lo, dense_hi = _slot_boxes(rng, S, A, K, n_real)
    u = rng.normal(size=S) * 3
    u[rng.random(S) < 0.3] = 0.5  # ties: lower index first
    u = np.where(slots[-1], u, 0.0).astype(np.float32)
    value = np.asarray(evi.sparse_optimistic_expectation(jnp.asarray(u), *slots))
    dense = np.asarray(optimistic_expectation(jnp.asarray(dense_lo, jnp.float32), jnp.asarray(dense_hi, jnp.float32),
                                              jnp.asarray(u)))
    np.testing.assert_allclose(value, dense, atol=2e-6)
    for s, a in [(0, 0), (S // 2, 1), (S - 1, 0)]:
        res = linprog(-u.astype(np.float64), A_eq=np.ones((1, S)), b_eq=[1.0],
                      bounds=list(zip(dense_lo[s, a], dense_hi[s, a])), method="highs")
        assert res.status == 0
        np.testing.assert_allclose(value[s, a], -res.fun, atol=2e-6)


def test_slot_boxes_evi_plans_as_the_dense_one(rng=np.random.default_rng(11)):
    """Same iterations, gain bounds and greedy policy (where not nearly tied) as the dense planner on the same boxes."""
    S, A, K = 60, 3, 4
    slots, dense_lo, dense_hi = _slot_boxes(rng, S, A, K, S - 3)
    r = jnp.asarray(rng.uniform(size=(S, A)), jnp.float32)
    masks = (slots[-1], jnp.ones(A, bool))
    fast = evi.sparse_extended_value_iteration(*slots[:4], r, *masks, tol=1e-4)
    p_hat, width = (dense_lo + dense_hi) / 2, (dense_hi - dense_lo) / 2
    dense = extended_value_iteration(jnp.asarray(p_hat, jnp.float32), jnp.asarray(width, jnp.float32), r, *masks,
                                     tol=1e-4)
    assert bool(fast.converged) and bool(dense.converged)
    assert int(fast.iterations) == int(dense.iterations)
    np.testing.assert_allclose([fast.gain_lower, fast.gain_upper], [dense.gain_lower, dense.gain_upper], atol=1e-5)
    real = np.asarray(slots[-1])
    np.testing.assert_allclose(np.asarray(fast.Q)[real], np.asarray(dense.Q)[real], atol=1e-4)
    Q = np.sort(np.asarray(dense.Q)[real], -1)
    clear = Q[:, -1] - Q[:, -2] > 1e-3
    greedy = lambda q: np.argmax(np.asarray(q)[real], -1)  # noqa: E731
    np.testing.assert_array_equal(greedy(fast.Q)[clear], greedy(dense.Q)[clear])


def test_eager_calls_compile_once_per_shape(caplog):
    # Both planners are jitted: a second eager call with other numbers of the same shapes compiles nothing.
    rng = np.random.default_rng(3)

    def calls():
        p_hat = jnp.asarray(rng.dirichlet(np.ones(3), size=(3, 2)), jnp.float32)
        r = jnp.asarray(rng.uniform(size=(3, 2)), jnp.float32)
        width, radius = jnp.full((3, 2, 3), 0.05), jnp.full((3, 2), 0.1)  # per next state; the reference's L1 radius
        masks = (jnp.ones(3, bool), jnp.ones(2, bool))
        return [lambda: extended_value_iteration(p_hat, width, r, *masks),
                lambda: evi.colosseum_extended_value_iteration(p_hat, radius, r, *masks)]

    assert compilations(caplog, calls())
    assert compilations(caplog, calls()) == []


def test_sorted_evi_plans_as_the_dense_one(monkeypatch, caplog, rng=np.random.default_rng(8)):
    """Same gain bounds, iterations and greedy policy within rounding (the sorted sweep differs in the last bits)."""
    S, A = evi.SORTED_FROM + 5, 3
    lo, hi, mask = _random_boxes(rng, S, A, n_padded=2)
    p_hat = np.asarray((lo + hi) / 2)  # any kernel inside the box; widths from the box
    width = np.asarray((hi - lo) / 2)
    r = jnp.asarray(rng.uniform(size=(S, A)), jnp.float32)
    args = (jnp.asarray(p_hat), jnp.asarray(width), r, jnp.asarray(mask), jnp.ones(A, bool))
    fast = extended_value_iteration(*args, tol=1e-4)
    monkeypatch.setattr(evi, "SORTED_FROM", 10**9)
    # The planner is jitted: without this the second call reuses the sorted program. (This test is the module's
    # last: clearing drops the programs the other tests compiled.)
    jax.clear_caches()
    rerun = []
    assert compilations(caplog, [lambda: rerun.append(extended_value_iteration(*args, tol=1e-4))])
    dense = rerun[0]
    assert not np.array_equal(fast.Q, dense.Q)  # the dense sweep ran: its last bits differ here
    assert bool(fast.converged) and bool(dense.converged)
    assert int(fast.iterations) == int(dense.iterations)
    np.testing.assert_allclose(fast.gain_lower, dense.gain_lower, atol=1e-5)
    np.testing.assert_allclose(fast.gain_upper, dense.gain_upper, atol=1e-5)
    np.testing.assert_allclose(fast.Q, dense.Q, atol=1e-4)
    np.testing.assert_array_equal(np.argmax(fast.Q, -1)[mask], np.argmax(dense.Q, -1)[mask])
