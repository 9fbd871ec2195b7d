"""Dynamic programming against independent numpy/scipy computations on small random MDPs.

Independent references: brute force over all deterministic stationary policies (discounted optimum, optimal gain),
plain numpy backward induction, numpy linear solves, and Cesàro averages of matrix powers in float64.
"""

import dataclasses
import functools
import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

import jaxmdp
from jaxmdp import dynamic_programming as dp
from jaxmdp.episodic import reachable_pairs
from jaxmdp.experiment.members import member_mdp

from conftest import compilations, random_mdp

GAMMA = 0.9


def np_policy_value(T, R, pi, gamma):
    P = np.einsum("sa,sat->st", pi, T)
    r = (pi * R).sum(-1)
    return np.linalg.solve(np.eye(len(r)) - gamma * P, r)


def deterministic_policies(S, A):
    for actions in itertools.product(range(A), repeat=S):
        yield np.eye(A)[list(actions)]


def cesaro_gain(P, r, n=20_000):
    """(1/n) sum_{t<n} P^t r in float64 (slow but independent)."""
    x, acc = r.copy(), np.zeros_like(r)
    for _ in range(n):
        acc += x
        x = P @ x
    return acc / n


@pytest.fixture(scope="module")
def mdps():
    rng = np.random.default_rng(0)
    return [random_mdp(rng, S=5, A=3) for _ in range(3)]


def test_q_values_match_dense_einsum(mdps):
    m = mdps[0]
    V = jnp.linspace(-1.0, 2.0, m.n_states)
    dense = np.asarray(m.R) + GAMMA * np.einsum("sat,t->sa", np.asarray(m.T), np.asarray(V))
    np.testing.assert_allclose(dp.q_values(m, V, GAMMA), dense, rtol=1e-6)
    np.testing.assert_allclose(dp.q_values(m.T, V, GAMMA, m.R), dense, rtol=1e-6)


def test_solve_discounted_equals_brute_force(mdps):
    for m in mdps:
        T, R = np.asarray(m.T, np.float64), np.asarray(m.R, np.float64)
        best = np.max([np_policy_value(T, R, pi, GAMMA) for pi in deterministic_policies(*R.shape)], axis=0)
        res = jax.jit(dp.solve_discounted, static_argnums=1)(m, GAMMA)
        assert bool(res.converged)
        np.testing.assert_allclose(res.V, best, rtol=2e-6)
        np.testing.assert_allclose(res.V, np.max(res.Q, -1), rtol=2e-6)


def test_value_iteration_respects_its_error_bound(mdps):
    m = mdps[1]
    exact = dp.solve_discounted(m, GAMMA).V
    tol = 1e-3
    vi = dp.value_iteration(m, GAMMA, tol=tol)
    assert bool(vi.converged)
    err = float(jnp.max(jnp.abs(vi.V - exact)))
    assert err <= GAMMA * tol / (1 - GAMMA)
    assert err > 0  # it stopped early: the bound is what is being tested


def test_value_iteration_reports_non_convergence(mdps):
    vi = dp.value_iteration(mdps[0], 0.999, tol=1e-9, max_iter=5)
    assert not bool(vi.converged) and int(vi.iterations) == 5


def test_policy_evaluation_matches_numpy_solve(mdps):
    m = mdps[2]
    rng = np.random.default_rng(1)
    pi = rng.dirichlet(np.ones(m.n_actions), size=m.n_states)
    Q, V = dp.policy_evaluation(m, jnp.asarray(pi, jnp.float32), GAMMA)
    V_np = np_policy_value(np.asarray(m.T, np.float64), np.asarray(m.R, np.float64), pi, GAMMA)
    np.testing.assert_allclose(V, V_np, rtol=1e-5)
    np.testing.assert_allclose(jnp.sum(Q * pi, -1), V_np, rtol=1e-5)


def test_finite_horizon_matches_numpy_backward_induction(mdps):
    m, H = mdps[0], 7
    T, R = np.asarray(m.T, np.float64), np.asarray(m.R, np.float64)
    V = np.zeros(m.n_states)
    Vs = [V]
    for _ in range(H):
        V = np.max(R + T @ V, axis=-1)
        Vs.append(V)
    Q, Vj = dp.finite_horizon_value_iteration(m.T, m.R, H=H)
    np.testing.assert_allclose(Vj, np.array(Vs[::-1]), rtol=1e-5)
    assert Q.shape == (H, m.n_states, m.n_actions)
    # Evaluating the greedy policy gives back the optimal values; the uniform policy matches numpy.
    _, Vg = dp.finite_horizon_policy_evaluation(m.T, dp.greedy(Q), m.R, H=H)
    np.testing.assert_allclose(Vg, Vj, rtol=1e-5)
    pi_u = np.full(R.shape, 1 / R.shape[1])
    V = np.zeros(m.n_states)
    for _ in range(H):
        V = ((R + T @ V) * pi_u).sum(-1)
    _, Vu = dp.finite_horizon_policy_evaluation(m.T, jnp.asarray(pi_u, jnp.float32), m.R, H=H)
    np.testing.assert_allclose(Vu[0], V, rtol=1e-5)


def test_traced_horizon_zeroes_late_steps(mdps):
    m = mdps[0]
    Q5, V5 = dp.finite_horizon_value_iteration(m.T, m.R, H=5)
    Q8, V8 = dp.finite_horizon_value_iteration(m.T, m.R, H=8, horizon=jnp.asarray(5))
    np.testing.assert_allclose(V8[0], V5[0], rtol=1e-6)
    np.testing.assert_array_equal(V8[5:], 0.0)


def test_greedy_breaks_ties_to_lowest_index_and_respects_mask():
    Q = jnp.array([[1.0, 3.0, 3.0], [2.0, 2.0, 2.0], [0.0, 0.0, 5.0]])
    np.testing.assert_array_equal(jnp.argmax(dp.greedy(Q), -1), [1, 0, 2])
    mask = jnp.array([True, True, False])
    np.testing.assert_array_equal(jnp.argmax(dp.greedy(Q, mask), -1), [1, 0, 0])
    np.testing.assert_array_equal(jnp.argmax(dp.greedy(jnp.array([[1.0, 1.0 - 1e-7]]), atol=1e-6), -1), [0])


def test_chain_gain_unichain_matches_scipy_null_space():
    rng = np.random.default_rng(3)
    P = rng.random((7, 7)) * (rng.random((7, 7)) < 0.6) + np.eye(7, k=1) + np.eye(7, k=-6)
    P /= P.sum(-1, keepdims=True)
    r = rng.random(7)
    mu = scipy.linalg.null_space((np.eye(7) - P).T)[:, 0]
    mu /= mu.sum()
    g = dp.chain_gain(jnp.asarray(P, jnp.float32), jnp.asarray(r, jnp.float32))
    np.testing.assert_allclose(g, np.full(7, mu @ r), rtol=1e-5)


def test_chain_gain_multichain_periodic_matches_cesaro_average():
    # States 0, 1 transient; {2, 3} a periodic closed class; {4} absorbing; {5, 6} a closed class.
    P = np.zeros((7, 7))
    P[0, [0, 1, 2, 4]] = [0.1, 0.3, 0.4, 0.2]
    P[1, [0, 5]] = [0.5, 0.5]
    P[2, 3] = P[3, 2] = 1.0
    P[4, 4] = 1.0
    P[5, [5, 6]] = [0.2, 0.8]
    P[6, [5, 6]] = [0.6, 0.4]
    r = np.array([0.3, 0.9, 1.0, 0.0, 0.25, 0.7, 0.1])
    g = dp.chain_gain(jnp.asarray(P, jnp.float32), jnp.asarray(r, jnp.float32))
    np.testing.assert_allclose(g, cesaro_gain(P, r), atol=2e-4)  # the Cesàro average itself has O(1/n) error
    # Closed forms: class {2,3} averages 0.5; class {5,6}: mu = (3/7, 4/7).
    np.testing.assert_allclose(np.asarray(g)[[2, 3, 4]], [0.5, 0.5, 0.25], rtol=1e-6)
    np.testing.assert_allclose(g[5], 3 / 7 * 0.7 + 4 / 7 * 0.1, rtol=1e-6)


def test_chain_gain_is_accurate_on_slowly_mixing_chains():
    # A lazy random walk on a 60-state path: a linear solve with I - P loses ~4 digits here, GTH does not.
    S = 60
    P = np.zeros((S, S))
    for s in range(S):
        P[s, max(s - 1, 0)] += 0.45
        P[s, min(s + 1, S - 1)] += 0.45
        P[s, s] += 0.1
    r = np.linspace(0.0, 1.0, S) ** 3
    mu = scipy.linalg.null_space((np.eye(S) - P).T)[:, 0]
    mu /= mu.sum()
    g = dp.chain_gain(jnp.asarray(P, jnp.float32), jnp.asarray(r, jnp.float32))
    np.testing.assert_allclose(g, mu @ r, rtol=2e-6)


def np_cesaro(P, x, n=4000):
    """Cesàro mean over ``n`` of the partial sums ``sum_{i<m} P^i x`` (the bias when ``x = r - g``)."""
    acc, y = np.zeros_like(x), x.copy()
    out = np.zeros_like(x)
    for _ in range(n):
        acc += y
        out += acc
        y = P @ y
    return out / n


def test_chain_bias_against_cesaro():
    rng = np.random.default_rng(5)
    P = rng.random((5, 5))
    P /= P.sum(1, keepdims=True)
    periodic = np.roll(np.eye(4), 1, axis=1)  # a 4-cycle: partial sums oscillate, the Cesàro limit exists
    for chain in (P, periodic):
        r = rng.random(chain.shape[0])
        h = np.asarray(dp.chain_bias(jnp.asarray(chain, jnp.float32), jnp.asarray(r, jnp.float32)))
        g = np.full_like(r, r @ np.linalg.matrix_power(0.5 * (np.eye(len(r)) + chain), 4000)[0])
        # (I - P) h = r - g and the Cesàro bias: mean over n of sum_{i<n} P^i (r - g).
        np.testing.assert_allclose((np.eye(len(r)) - chain) @ h, r - g, atol=2e-5)
        np.testing.assert_allclose(h, np_cesaro(chain, r - g), atol=2e-3)


def test_optimal_gain_equals_brute_force_over_policies():
    rng = np.random.default_rng(5)
    for _ in range(3):
        m = random_mdp(rng, S=5, A=2, sparsity=0.7)
        T, R, P0 = (np.asarray(x, np.float64) for x in (m.T, m.R, m.P0))
        gains = [
            P0 @ cesaro_gain(np.einsum("sa,sat->st", pi, T), (pi * R).sum(-1), n=4000)
            for pi in deterministic_policies(5, 2)
        ]
        res = jax.jit(dp.optimal_gain)(m)
        assert bool(res.converged)
        np.testing.assert_allclose(res.gain, max(gains), rtol=1e-3)
        assert float(res.lower) - 1e-5 <= float(res.gain) <= float(res.upper) + 1e-5


def test_optimal_gain_of_deterministic_river_swim():
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, randomize_actions=False)
    res = dp.optimal_gain(m)
    np.testing.assert_allclose(res.gain, 1.0, rtol=1e-6)
    np.testing.assert_array_equal(jnp.argmax(res.policy, -1)[:4], [1, 1, 1, 1])


def test_optimal_gain_stops_at_the_round_off_floor_with_the_policy_of_the_full_run():
    # Two states that swap with probability 1e-3 (action 1 of state 1 with 2e-3), reward 1 in state 0: the bias gap
    # is about 500, whose float32 spacing (6e-5) keeps the span of T h - h above tol (1e-6 (1 + rho)). Without the
    # stall rule the iteration runs all max_iter sweeps; with it, it stops after `patience` sweeps without a smaller
    # span, with the same policy, gain and bounds.
    eps = 1e-3
    T = np.zeros((2, 2, 2))
    T[0, :] = [1 - eps, eps]
    T[1, 0], T[1, 1] = [eps, 1 - eps], [2 * eps, 1 - 2 * eps]
    mean = np.zeros((2, 2, 2))
    mean[0] = 1.0
    m = jaxmdp.custom_mdp(T, P0=np.array([0.5, 0.5]), reward_mean=mean)
    full = dp.optimal_gain(m, max_iter=50_000, patience=50_000)
    early = dp.optimal_gain(m, max_iter=50_000)
    assert int(full.iterations) == 50_000 and not bool(full.converged)
    assert int(early.iterations) < 10_000 and not bool(early.converged)
    np.testing.assert_array_equal(early.policy, full.policy)
    np.testing.assert_array_equal(early.policy, [[1.0, 0.0], [0.0, 1.0]])  # state 1 leaves faster
    np.testing.assert_allclose(early.gain, 2.0 / 3.0, rtol=1e-6)  # stationary mass of state 0: 2 eps / (3 eps)
    np.testing.assert_allclose([early.lower, early.upper], [full.lower, full.upper], atol=2e-5)
    # A span that shrinks to tol stops as before: same sweeps, same numbers.
    river = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5)
    a, b = dp.optimal_gain(river), dp.optimal_gain(river, patience=200_000)
    assert bool(a.converged) and int(a.iterations) == int(b.iterations)
    np.testing.assert_array_equal(a.bias, b.bias)


def test_dp_vmaps_over_mdps_and_policies(mdps):
    batch = jaxmdp.stack(mdps)
    Vb = jax.vmap(lambda m: dp.solve_discounted(m, GAMMA).V)(batch.strip())
    for i, m in enumerate(mdps):
        np.testing.assert_allclose(Vb[i, : m.n_states], dp.solve_discounted(m, GAMMA).V, rtol=1e-5)
    m = mdps[0]
    pis = jax.random.dirichlet(jax.random.key(0), jnp.ones(m.n_actions), (4, m.n_states))
    Vp = jax.vmap(lambda pi: dp.policy_evaluation(m, pi, GAMMA)[1])(pis)
    for i in range(4):
        np.testing.assert_allclose(Vp[i], dp.policy_evaluation(m, pis[i], GAMMA)[1], rtol=1e-6)


def test_chain_gain_survives_stationary_masses_beyond_float32_range():
    # A birth-death chain drifting right: mu(s) grows like 9^s, i.e. a ratio of ~1e47 over 50 states.
    S = 50
    P = np.zeros((S, S))
    for s in range(S):
        P[s, min(s + 1, S - 1)] += 0.9
        P[s, max(s - 1, 0)] += 0.1
    r = np.zeros(S)
    r[-1], r[0] = 1.0, 0.5
    g = dp.chain_gain(jnp.asarray(P, jnp.float32), jnp.asarray(r, jnp.float32))
    mu = scipy.linalg.null_space((np.eye(S) - P).T)[:, 0]
    mu /= mu.sum()
    assert bool(jnp.all(jnp.isfinite(g)))
    np.testing.assert_allclose(g, mu @ r, rtol=1e-6)


def test_deterministic_evaluation_matches_numpy_and_the_one_hot_policy():
    # An episodic MDP on successor lists and a random time-indexed deterministic policy: numpy backward induction
    # on the dense kernel (independent), and the one-hot policy's evaluation bit for bit (it only adds exact zeros).
    rng = np.random.default_rng(3)
    m = random_mdp(rng, S=6, A=3, H=5)
    actions = rng.integers(0, m.n_actions, size=(m.H, m.n_states))
    T, R = np.asarray(m.T, np.float64), np.asarray(m.R, np.float64)
    V, Vs = np.zeros(m.n_states), []
    for h in reversed(range(m.H)):
        V = R[np.arange(m.n_states), actions[h]] + T[np.arange(m.n_states), actions[h]] @ V
        Vs.append(V)
    V_det = dp.finite_horizon_deterministic_evaluation(m, jnp.asarray(actions, jnp.int32))
    np.testing.assert_allclose(V_det[:-1], np.array(Vs[::-1]), rtol=1e-6)
    np.testing.assert_array_equal(V_det[-1], 0.0)
    one_hot = jax.nn.one_hot(actions, m.n_actions, dtype=m.R.dtype)
    _, V_pi = dp.finite_horizon_policy_evaluation(m, one_hot)
    np.testing.assert_array_equal(np.asarray(V_det), np.asarray(V_pi))
    # A traced horizon below H zeroes the late steps in both forms.
    short = m.replace(horizon=jnp.asarray(3, m.horizon.dtype))
    V_short = dp.finite_horizon_deterministic_evaluation(short, jnp.asarray(actions, jnp.int32))
    np.testing.assert_array_equal(np.asarray(V_short), np.asarray(dp.finite_horizon_policy_evaluation(short, one_hot)[1]))
    np.testing.assert_array_equal(V_short[3:], 0.0)
    # V_0 alone (what the indicators read): the very numbers of the full backward pass, either horizon.
    for mdp, V_full in ((m, V_det), (short, V_short)):
        V_0 = dp.finite_horizon_deterministic_start_values(mdp, jnp.asarray(actions, jnp.int32))
        np.testing.assert_array_equal(np.asarray(V_0), np.asarray(V_full[0]))


def test_start_values_read_from_a_stack_of_mdps():
    # Rows read from a stacked MDP's packed table by (member, s, a), vmapped over members as the runner does: the
    # very numbers of each member's own evaluation, also for the smaller, padded MDP of the stack.
    rng = np.random.default_rng(5)
    mdps = [random_mdp(rng, S=6, A=3, H=5), random_mdp(rng, S=4, A=2, H=3)]
    stack = jaxmdp.stack(mdps).strip()
    rows = dp.successor_rows(stack)
    assert rows.shape == (2, 6, 3, 2 * stack.succ.shape[-1] + 1)
    index = jnp.asarray([0, 1, 1, 0])
    actions = jnp.asarray(rng.integers(0, 2, size=(4, stack.H, 6)), jnp.int32)
    member = functools.partial(member_mdp, stack)
    from_stack = jax.jit(jax.vmap(lambda i, a: dp.finite_horizon_deterministic_start_values(member(i), a, rows, i)))
    own = [dp.finite_horizon_deterministic_start_values(member(i), actions[b]) for b, i in enumerate(index)]
    np.testing.assert_array_equal(np.asarray(from_stack(index, actions)), np.stack(own))
    with pytest.raises(ValueError, match="rows and member go together"):
        dp.finite_horizon_deterministic_start_values(member(0), actions[0], rows)


def test_start_values_are_the_first_step_of_policy_evaluation():
    # Stochastic policies, time-indexed and stationary, a traced horizon below H: V_0 bit for bit, and against an
    # independent float64 backward induction.
    rng = np.random.default_rng(4)
    m = random_mdp(rng, S=7, A=3, H=6)
    T, R = np.asarray(m.T, np.float64), np.asarray(m.R, np.float64)
    for pi in (rng.dirichlet(np.ones(3), size=(m.H, m.n_states)), rng.dirichlet(np.ones(3), size=m.n_states)):
        pi = jnp.asarray(pi, jnp.float32)
        for horizon in (m.H, 4):
            mdp = m.replace(horizon=jnp.asarray(horizon, m.horizon.dtype))
            V_0 = dp.finite_horizon_start_values(mdp, pi)
            np.testing.assert_array_equal(np.asarray(V_0), np.asarray(dp.finite_horizon_policy_evaluation(mdp, pi)[1][0]))
            pis, V = np.broadcast_to(np.asarray(pi, np.float64), (m.H, m.n_states, 3)), np.zeros(m.n_states)
            for h in reversed(range(horizon)):
                V = np.sum(pis[h] * (R + T @ V), axis=-1)
            np.testing.assert_allclose(V_0, V, rtol=1e-5)


def test_greedy_actions_is_the_index_of_greedy():
    Q = jnp.array([[1.0, 3.0, 3.0], [2.0, 2.0, 2.0], [0.0, 0.0, 5.0]])
    mask = jnp.array([True, True, False])
    np.testing.assert_array_equal(dp.greedy_actions(Q), [1, 0, 2])
    np.testing.assert_array_equal(dp.greedy_actions(Q, mask), [1, 0, 0])
    wide = jax.random.normal(jax.random.key(0), (4, 20)).at[0, 7].set(9.0).at[0, 11].set(9.0)  # argmax path
    np.testing.assert_array_equal(dp.greedy_actions(wide)[0], 7)
    for q in (Q, wide):
        np.testing.assert_array_equal(jax.nn.one_hot(dp.greedy_actions(q), q.shape[-1]), dp.greedy(q))


def np_closure(adj):
    """Reflexive-transitive closure of a boolean adjacency matrix by Warshall's algorithm (numpy, independent)."""
    reach = adj | np.eye(len(adj), dtype=bool)
    for k in range(len(adj)):
        reach |= reach[:, [k]] & reach[[k], :]
    return reach


def test_successor_reachability_matches_warshall():
    # Sparse random successor lists over 1 to 70 states (bit sets of one to three words, 32 states a word), slots
    # masked at random, a long path (many sweeps) and a cycle: the closure equals Warshall's on the same edges.
    rng = np.random.default_rng(7)
    cases = []
    for S in (1, 5, 32, 33, 70):
        succ = rng.integers(0, S, size=(S, 2, 3))
        cases.append((succ, rng.random((S, 2, 3)) < 0.25))
    path = np.minimum(np.arange(70) + 1, 69)[:, None]
    cases += [(path, np.ones((70, 1), bool)), ((np.arange(40) + 1)[:, None] % 40, np.ones((40, 1), bool))]
    reach = jax.jit(dp.successor_reachability)
    for succ, edge in cases:
        S = succ.shape[0]
        adj = np.zeros((S, S), bool)
        rows = np.broadcast_to(np.arange(S).reshape((S,) + (1,) * (succ.ndim - 1)), succ.shape)
        adj[rows[edge], succ[edge]] = True
        got = np.asarray(reach(jnp.asarray(succ, jnp.int32), jnp.asarray(edge)))
        np.testing.assert_array_equal(got, np_closure(adj))


@pytest.mark.nightly  # by default: test_gth_banded.py's gain vectors against float64
def test_gain_vector_from_successor_reachability_equals_the_dense_route():
    # gain_vector on an MDP takes the recurrent classes from the successor lists; chain_gain on the dense policy
    # matrix squares the adjacency instead. Same edges, so the same classes and bitwise the same gains, on random
    # sparse MDPs with deterministic (multichain) and stochastic policies.
    rng = np.random.default_rng(12)
    gain = jax.jit(dp.gain_vector)
    dense = jax.jit(lambda m, pi: dp.chain_gain(dp.policy_matrix(m, pi), dp.policy_rewards(m, pi)))
    classes = jax.jit(lambda m, pi: dp.recurrent_classes(dp.policy_matrix(m, pi)))
    for trial in range(8):
        mdp = random_mdp(rng, S=11, A=3, sparsity=(0.05, 0.2)[trial % 2])
        pi = np.eye(3)[rng.integers(0, 3, 11)] if trial % 2 else rng.dirichlet(np.ones(3), 11) * (rng.random((11, 3)) < .6)
        pi = jnp.asarray(pi / np.maximum(pi.sum(-1, keepdims=True), 1e-9) + (pi.sum(-1, keepdims=True) == 0) / 3,
                         jnp.float32)
        reach = dp.successor_reachability(mdp.succ, pi[:, :, None] * mdp.succ_p > 0)
        for a, b in zip(dp.recurrent_classes(dp.policy_matrix(mdp, pi), reach), classes(mdp, pi)):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(gain(mdp, pi), dense(mdp, pi))


def _eager_calls(mdp: jaxmdp.MDP, episodic: jaxmdp.MDP) -> list:
    """One eager call of every routine that loops (dynamic_programming.compiled), on ``mdp`` (continuous) and
    ``episodic``."""
    pi = dp.uniform_policy(mdp)
    P, r = dp.policy_matrix(mdp, pi), dp.policy_rewards(mdp, pi)
    actions = jnp.zeros((episodic.H, episodic.n_states), jnp.int32)
    return [
        lambda: dp.value_iteration(mdp, 0.9),
        lambda: dp.policy_iteration(mdp, 0.9),
        lambda: dp.solve_discounted(mdp, 0.9),
        lambda: dp.finite_horizon_value_iteration(episodic),
        lambda: dp.finite_horizon_value_iteration(mdp.T, mdp.R, H=3),
        lambda: dp.finite_horizon_policy_evaluation(episodic, dp.uniform_policy(episodic)),
        lambda: dp.finite_horizon_deterministic_evaluation(episodic, actions),
        lambda: dp.finite_horizon_start_values(episodic, dp.uniform_policy(episodic)),
        lambda: dp.finite_horizon_deterministic_start_values(episodic, actions),
        lambda: dp.recurrent_classes(P),
        lambda: dp.successor_reachability(mdp.succ, mdp.succ_p > 0),
        lambda: dp.chain_gain(P, r),
        lambda: dp.chain_bias(P, r),
        lambda: dp.cesaro_limit(P),
        lambda: dp.gain_vector(mdp, pi),
        lambda: dp.successor_gain_bounds(mdp, pi),
        lambda: dp.policy_gain(mdp, pi),
        lambda: dp.optimal_gain(mdp),
        lambda: jaxmdp.reference_values(mdp, "colosseum"),
        lambda: jaxmdp.reference_values(episodic),
        lambda: reachable_pairs(episodic),
    ]


@pytest.mark.nightly  # by default: test_hardness_diameter.py's eager-compile test (the same dp.compiled)
def test_eager_calls_compile_once_per_shape(caplog):
    """The routines with loops are jitted with their MDPs' labels stripped (dynamic_programming.compiled): a second
    eager call with the same shapes compiles nothing, also on another MDP of those shapes with other labels (without
    the jit their loops compiled again at every call, about 1 s each on the 2-core CPU)."""
    def relabelled(m):
        return m.replace(info=dataclasses.replace(m.info, node_labels=tuple(f"other {i}" for i in range(m.n_states))))

    continuous = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)
    episodic = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4)
    assert relabelled(continuous).info != continuous.info
    assert compilations(caplog, _eager_calls(continuous, episodic))  # the first calls compile
    assert compilations(caplog, _eager_calls(continuous, episodic)) == []
    assert compilations(caplog, _eager_calls(relabelled(continuous), relabelled(episodic))) == []
