"""Parity of every array of every reference fixture (../shared/reference/colosseum; README there): optimal ``Q*``/``V*``,
the worst and random policies' values, the optimal policy (up to ties), the episodic reachable pairs and their order,
and the reward-distribution parameters.

Tolerances follow from how the reference computed each array (README, "What the package computes"):

* continuous ``Q*``/``V*``: value iteration with ``gamma = 0.99`` stopped when a sweep changes ``V`` by less than
  ``eps = 1e-3``, so ``|V - V*| <= gamma eps / (1 - gamma) = 0.099`` (a sup-norm contraction; Puterman Thm 6.3.3);
* continuous ``V_worst``: the greedy policy of that value iteration on ``-R`` is ``2 gamma eps / (1 - gamma) =
  0.198``-optimal for ``-R`` (Puterman Thm 6.3.1), evaluated to ``1e-7``; ``V_random``: an evaluation to ``1e-7``;
* episodic: exact backward induction in float32 (relative ``1e-5``);
* the optimal policy: its action is optimal up to the same slack (ties broken at random by the reference).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import build_reference_mdp, load_reference, reference_params
from jaxmdp import dynamic_programming as dp
from jaxmdp import episodic

GAMMA, EPS = 0.99, 1e-3
VI_SLACK = GAMMA * EPS / (1 - GAMMA)
GREEDY_SLACK = 2 * GAMMA * EPS / (1 - GAMMA)
F32 = 1e-5  # float32 round-off, relative

_solve = jax.jit(lambda m, r: dp.solve_discounted(m, GAMMA, rewards=r))
_evaluate = jax.jit(lambda m, pi: dp.policy_evaluation(m, pi, GAMMA))
_finite = jax.jit(dp.finite_horizon_value_iteration)
_finite_eval = jax.jit(dp.finite_horizon_policy_evaluation)


@pytest.fixture(scope="module")
def cases():
    cache = {}

    def get(entry):
        if entry["id"] not in cache:
            m = build_reference_mdp(entry)
            cache[entry["id"]] = (m, load_reference(entry))
        return cache[entry["id"]]

    return get


def _uniform(m):
    mask = np.asarray(m.action_mask, np.float64)
    return jnp.asarray(np.broadcast_to(mask / mask.sum(), (m.n_states, m.n_actions)), m.dtype)


@pytest.mark.parametrize("entry", reference_params(every=False))
def test_value_arrays(entry, cases):
    m, ref = cases(entry)
    m = m.strip()
    scale = max(1.0, float(np.abs(ref["V_star"]).max()))
    if entry["setting"] == "continuous":
        opt = _solve(m, m.R)
        np.testing.assert_allclose(opt.Q, ref["Q_star"], atol=VI_SLACK + F32 * scale, rtol=0)
        np.testing.assert_allclose(opt.V, ref["V_star"], atol=VI_SLACK + F32 * scale, rtol=0)
        worst = -np.asarray(_solve(m, -m.R).V, np.float64)  # exact minimal values
        assert np.all(ref["V_worst"] >= worst - F32 * scale)
        assert np.all(ref["V_worst"] <= worst + GREEDY_SLACK + F32 * scale)
        random = _evaluate(m, _uniform(m))
        np.testing.assert_allclose(random[1], ref["V_random"], atol=F32 * scale, rtol=0)
        Q = np.asarray(opt.Q, np.float64)
        slack = GREEDY_SLACK + F32 * scale
    else:
        Q, V = (np.asarray(x, np.float64) for x in _finite(m))
        H = m.H
        np.testing.assert_allclose(Q, ref["Q_star"][:H], atol=F32 * scale, rtol=0)
        np.testing.assert_allclose(V, ref["V_star"], atol=F32 * scale, rtol=0)
        _, V_min = _finite(m, -m.R)
        np.testing.assert_allclose(-np.asarray(V_min), ref["V_worst"], atol=F32 * scale, rtol=0)
        _, V_rand = _finite_eval(m, _uniform(m))
        np.testing.assert_allclose(V_rand, ref["V_random"], atol=F32 * scale, rtol=0)
        slack = F32 * scale
    # The reference's greedy action is optimal up to the slack (it breaks ties at random).
    pi = np.asarray(ref["optimal_policy"]).astype(int)[: Q.shape[0]] if Q.ndim == 3 else np.asarray(
        ref["optimal_policy"]).astype(int)
    chosen = np.take_along_axis(Q, pi[..., None], -1)[..., 0]
    assert np.all(chosen >= Q.max(-1) - slack)


@pytest.mark.parametrize("entry", [p for p in reference_params() if p.values[0] is None
                                   or p.values[0]["setting"] == "episodic"])
def test_reachable_pairs_and_their_order(entry, cases):
    m, ref = cases(entry)
    reach = np.asarray(episodic.reachable_pairs(m))
    np.testing.assert_array_equal(np.argwhere(reach), np.array(sorted(map(tuple, ref["reachable_states"]))))
    np.testing.assert_array_equal(episodic.episodic_graph_order(m), ref["episodic_graph_nodes"])


@pytest.mark.parametrize("entry", reference_params())
def test_reward_distribution_parameters(entry, cases):
    m, ref = cases(entry)
    mean, conc = np.asarray(m.reward_mean, np.float64), np.asarray(m.reward_conc, np.float64)
    T = np.zeros(mean.shape)
    for s, a, t, p, dist, args, mu in zip(ref["reward_entry_s"], ref["reward_entry_a"], ref["reward_entry_next_s"],
                                          ref["reward_entry_prob"], ref["reward_entry_dist"],
                                          ref["reward_entry_args"], ref["reward_entry_mean"]):
        T[s, a, t] += p
        assert mean[s, a, t] == pytest.approx(mu, abs=1e-6), (s, a, t)
        if str(dist) == "beta":
            # Beta(alpha, beta) = mean and concentration alpha + beta.
            assert conc[s, a, t] == pytest.approx(args[0] + args[1], rel=1e-5), (s, a, t)
            assert mu == pytest.approx(args[0] / (args[0] + args[1]), rel=1e-6)
        else:
            assert str(dist) == "deterministic" and conc[s, a, t] == 0.0 and mu == pytest.approx(args[0], abs=1e-7)
    np.testing.assert_allclose(T, ref["T"], atol=1e-6)
