"""Property tests: jaxmdp's optimal values against independent numpy solvers, and the noise transforms at 0, on random
MDPs (tests/random_mdps.py; Hypothesis profiles in tests/hypothesis_profiles.py).

Every draw is padded to one canonical shape (5 states, 3 actions, episodes of static length 4), so each jitted
function below compiles once per module. The numpy side enumerates deterministic policies (discounted values,
gains) or runs backward induction with explicit loops in float64 on the real states only.
"""

from __future__ import annotations

import hypothesis_profiles
import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import jaxmdp
from jaxmdp import dynamic_programming as dp
from random_mdps import (
    Draw,
    chain_gain,
    discounted_optimal,
    draws,
    finite_horizon_optimal,
    optimal_gain_vector,
)

examples = hypothesis_profiles.examples

# float32 arithmetic on values of at most 1 / (1 - gamma) = 100 (rewards in [0, 1]).
F32 = 2e-5


@jax.jit
def _discounted(mdp, gamma):
    return dp.solve_discounted(mdp, gamma).V, dp.value_iteration(mdp, gamma, tol=1e-4)


@given(draw=draws(episodic=False), gamma=st.sampled_from([0.5, 0.9, 0.99]))
@settings(max_examples=examples(40))
def test_discounted_values_match_policy_enumeration(draw: Draw, gamma: float):
    T, R, _ = draw.arrays()
    S = draw.n_states
    _, V_star = discounted_optimal(T, R, gamma)
    V_exact, vi = _discounted(draw.padded(), jnp.float32(gamma))
    V_exact, V_vi = np.asarray(V_exact, np.float64), np.asarray(vi.V, np.float64)
    scale = F32 * (1 + np.max(np.abs(V_star))) / (1 - gamma)
    # solve_discounted: policy iteration stops within eps = 1e-5 (1 + max|V|) of greedy, so
    # V* - eps / (1 - gamma) <= V <= V* (its docstring), plus float32 evaluation error.
    eps = 1e-5 * (1 + np.max(np.abs(V_exact))) / (1 - gamma)
    assert np.all(V_exact[:S] <= V_star + scale), (V_exact[:S], V_star)
    assert np.all(V_exact[:S] >= V_star - eps - scale), (V_exact[:S], V_star)
    # value_iteration: ||V - V*|| <= gamma tol / (1 - gamma) once converged.
    assert bool(vi.converged)
    np.testing.assert_allclose(V_vi[:S], V_star, rtol=0, atol=gamma * 1e-4 / (1 - gamma) + scale)
    # Padding states are absorbing and pay nothing.
    assert np.all(V_exact[S:] == 0) and np.all(V_vi[S:] == 0)


@jax.jit
def _episodic(mdp):
    Q, V = dp.finite_horizon_value_iteration(mdp)
    return V, jaxmdp.reference_values(mdp)


@given(draw=draws(episodic=True))
@settings(max_examples=examples(40))
def test_backward_induction_matches_numpy(draw: Draw):
    T, R, P0 = draw.arrays()
    S, A, H = draw.n_states, draw.n_actions, draw.horizon
    V_star = finite_horizon_optimal(T, R, H)
    V_worst = -finite_horizon_optimal(T, -R, H)
    V, ref = _episodic(draw.padded())
    tol = F32 * (1 + H)
    np.testing.assert_allclose(np.asarray(V[0, :S], np.float64), V_star[0], rtol=0, atol=tol)
    assert np.all(np.asarray(V[:, S:]) == 0)
    np.testing.assert_allclose(float(ref.optimal), P0 @ V_star[0], rtol=0, atol=tol)
    np.testing.assert_allclose(float(ref.worst), P0 @ V_worst[0], rtol=0, atol=tol)
    # The uniformly random policy over the real actions, by backward induction in numpy.
    V_rand = np.zeros(S)
    for _ in range(H):
        V_rand = (R + T @ V_rand).mean(-1)
    np.testing.assert_allclose(float(ref.random), P0 @ V_rand, rtol=0, atol=tol)
    # The optimal policy is greedy at every in-episode time and picks no padded action.
    pi = np.asarray(ref.optimal_policy)
    assert np.all(pi[:, :, A:] == 0)


@jax.jit
def _gain(mdp):
    return dp.optimal_gain(mdp, max_iter=5_000), dp.optimal_gain(mdp, rewards=-mdp.R, max_iter=5_000)


_reference_values = jax.jit(jaxmdp.reference_values, static_argnames="variant")


def _policy_gain(T, R, P0, pi):
    """Exact gain from ``P0`` of a stationary policy ``pi[S, A]`` (numpy, closed classes of its chain)."""
    P = np.einsum("sa,sat->st", pi, T)
    return P0 @ chain_gain(P, (pi * R).sum(-1))


@given(draw=draws(episodic=False))
@settings(max_examples=examples(25))
def test_optimal_gain_matches_policy_enumeration(draw: Draw):
    """``optimal_gain`` is gain-optimal whenever the optimal gain is the same from every state (weakly communicating
    MDPs, and multichain ones whose classes tie), and says so (``converged``); otherwise it says it did not converge
    and its policy's gain is no better than the optimum. Its reported gain is its policy's exact gain."""
    T, R, P0 = draw.arrays()
    S, A = draw.n_states, draw.n_actions
    mdp = draw.padded()
    best, best_neg = optimal_gain_vector(T, R), optimal_gain_vector(T, -R)
    res, res_neg = _gain(mdp)
    for r, g_star, sign in ((res, best, 1.0), (res_neg, best_neg, -1.0)):
        pi = np.asarray(r.policy, np.float64)
        assert np.all(pi[:S, A:] == 0)
        own = _policy_gain(T, sign * R, P0, pi[:S, :A])
        np.testing.assert_allclose(float(r.gain), own, rtol=0, atol=1e-4)
        constant = np.ptp(g_star) < 1e-9
        assert bool(r.converged) == constant, (bool(r.converged), g_star)
        if constant:
            np.testing.assert_allclose(float(r.gain), P0 @ g_star, rtol=0, atol=1e-4)
            assert float(r.lower) <= g_star[0] + 1e-4 and g_star[0] <= float(r.upper) + 1e-4
        else:
            assert float(r.gain) <= P0 @ g_star + 1e-4
    if np.ptp(best) < 1e-9 and np.ptp(best_neg) < 1e-9:
        # reference_values runs optimal_gain to its default budget: only where it converges.
        ref = _reference_values(mdp, "paper")
        np.testing.assert_allclose([float(ref.optimal), float(ref.worst)], [P0 @ best, -(P0 @ best_neg)], atol=1e-4)
        uniform = np.full((S, A), 1.0 / A)
        np.testing.assert_allclose(float(ref.random), _policy_gain(T, R, P0, uniform), atol=1e-4)
    # The colosseum variant: the gamma = 0.99 greedy policies, evaluated exactly; never better than the optimum.
    ref = _reference_values(mdp, "colosseum")
    pi = np.asarray(ref.optimal_policy, np.float64)[:S, :A]
    np.testing.assert_allclose(float(ref.optimal), _policy_gain(T, R, P0, pi), atol=1e-4)
    assert float(ref.optimal) <= P0 @ best + 1e-4
    assert float(ref.worst) >= -(P0 @ best_neg) - 1e-4


# ---------------------------------------------------------------------------------------------------------------
# p_rand = 0 and p_lazy = 0 leave the MDP unchanged
# ---------------------------------------------------------------------------------------------------------------


def _dense_from_lists(succ, succ_p, S):
    out = np.zeros(succ.shape[:2] + (S,))
    for s, a, k in np.ndindex(*succ.shape):
        out[s, a, succ[s, a, k]] += succ_p[s, a, k]
    return out


@jax.jit
def _transformed(mdp, p, keys, states, actions):
    """Both transforms at ``p`` (traced) and a batch of steps on each and on the original MDP."""
    out = {"p_rand": jaxmdp.apply_p_rand(mdp, p), "p_lazy": jaxmdp.apply_p_lazy(mdp, p)}

    def steps(m):
        def one(key, s, a):
            return jaxmdp.step(key, jaxmdp.EnvState(s, jnp.int32(0)), a, m)

        return jax.vmap(one)(keys, states, actions)

    return out, {name: steps(m) for name, m in [("base", mdp), *out.items()]}


@given(draw=st.booleans().flatmap(lambda e: draws(episodic=e)), seed=st.integers(0, 2**31 - 1))
@settings(max_examples=examples(20))
def test_noise_transforms_at_zero_leave_the_mdp_unchanged(draw: Draw, seed: int):
    mdp = draw.padded()
    S, A = draw.n_states, draw.n_actions
    n = 64
    rng = np.random.default_rng(seed)
    keys = jax.random.split(jax.random.key(seed), n)
    states = jnp.asarray(rng.integers(0, S, n), jnp.int32)
    actions = jnp.asarray(rng.integers(0, A, n), jnp.int32)
    out, stepped = _transformed(mdp, jnp.float32(0.0), keys, states, actions)
    T = np.asarray(mdp.T)
    for name, m in out.items():
        np.testing.assert_array_equal(np.asarray(m.T), T, err_msg=name)
        np.testing.assert_allclose(np.asarray(m.R), np.asarray(mdp.R), rtol=0, atol=1e-6, err_msg=name)
        for field in ("P0", "reward_mean", "reward_conc", "start", "start_cdf", "state_mask", "action_mask",
                      "horizon"):
            np.testing.assert_array_equal(np.asarray(getattr(m, field)), np.asarray(getattr(mdp, field)),
                                          err_msg=f"{name}: {field}")
        # The successor lists (longer after a transform) describe the same kernel.
        dense = _dense_from_lists(np.asarray(m.succ), np.asarray(m.succ_p, np.float64), S_all := T.shape[0])
        np.testing.assert_allclose(dense, T, rtol=0, atol=1e-7, err_msg=f"{name}: successor lists ({S_all} states)")
        # The same keys give the same steps, bit for bit.
        for a, b in zip(jax.tree.leaves(stepped["base"]), jax.tree.leaves(stepped[name])):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=f"{name}: step")
