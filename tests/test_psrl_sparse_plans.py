"""PSRL continuous's plan (candidates on the successor slots, agents.extended_policy_iteration) gives the plans of the
dense construction: per key against the float64 optimum of the dense extended MDP of the same draws, and in
distribution against an independent numpy implementation of Agrawal & Jia's candidates (its own random numbers, its
own ``p^-``, Dirichlet and Normal-Gamma draws, its own float64 policy iteration)."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import agents.extended_policy_iteration as epi
import jaxmdp
import numpy_reference
from agents import estimated_model as em
from agents import get
from agents.posteriors import normal_gamma_sample
from jaxmdp.experiment.agent_interface import spec_of
from stat_checks import Checks, key, rng

# 4 real states and a padded one (index 2); 2 real actions and a padded one; psi = 3 of max_psi = 4, eta = 5.
S, A = 5, 3
STATE_MASK = np.array([True, True, False, True, True])
ACTION_MASK = np.array([True, True, False])
REAL_S, REAL_A = np.flatnonzero(STATE_MASK), np.flatnonzero(ACTION_MASK)
GAMMA = 0.99


def _state(counts: np.ndarray, mu: np.ndarray, reward_count: float):
    """The agent's state with next-state counts ``counts[4, 2, 4]`` on the real pairs and a Normal-Gamma reward
    posterior of mean ``mu[4, 2]`` after ``reward_count`` unit-variance observations per pair."""
    agent = get("psrl_continuous")
    mdp = jaxmdp.custom_mdp(np.full((S, A, S), 1.0 / S), R=np.zeros((S, A)))
    spec = spec_of(mdp, 500_000).replace(state_mask=jnp.asarray(STATE_MASK), action_mask=jnp.asarray(ACTION_MASK))
    hp = agent.default_hparams.replace(max_psi=4, psi_weight=0.16, eta_weight=0.0, discount=GAMMA)
    state = agent.init(jax.random.key(0), spec, hp)
    full = np.zeros((S, A, S), np.int32)
    full[np.ix_(REAL_S, REAL_A, REAL_S)] = counts
    M = np.zeros((S, A), np.float32)
    M[np.ix_(REAL_S, REAL_A)] = mu
    n = 1.0 + reward_count
    rewards = state.rewards.replace(mu=jnp.asarray(M), lam=jnp.full((S, A), n, jnp.float32),
                                    alpha=jnp.full((S, A), n / 2, jnp.float32),
                                    beta=jnp.full((S, A), n / 2, jnp.float32))
    state = state.replace(successors=em.with_dense_counts(state.successors, jnp.asarray(full)),
                          schedule=state.schedule.replace(visits=jnp.asarray(full.sum(-1))), rewards=rewards)
    assert int(state.constants.psi) == 3 and float(state.constants.eta) == 5.0
    return agent, state


def _random_counts(g: np.random.Generator, at_eta: float) -> np.ndarray:
    """Counts of 4 x 2 real pairs: a fraction ``at_eta`` of them with 5-12 visits (at eta), the rest 0-4."""
    hot = g.random((4, 2)) < at_eta
    visits = np.where(hot, g.integers(5, 13, (4, 2)), g.integers(0, 5, (4, 2)))
    return np.stack([[g.multinomial(visits[s, a], g.dirichlet(np.ones(4))) for a in range(2)] for s in range(4)])


@functools.partial(jax.jit, static_argnames="variant")
def _plans_and_dense(keys, state, variant):
    """Per key: the plan's ``(Q, u)`` and the dense extended MDP of its draws ``(T, R_ext)``."""
    agent = get("psrl_continuous", variant)

    def one(k):
        new = agent.plan(k, state)
        k_r, k_p = jax.random.split(k)
        R = normal_gamma_sample(k_r, state.rewards)
        T, R_ext, _ = epi.extended_mdp(R, epi.candidate_kernels(k_p, state, variant=variant), state.action_mask)
        if variant == "colosseum":
            R_ext = epi.colosseum_extended_rewards(R, state.constants.psi, state.hparams.max_psi, state.action_mask)
        return new.Q, new.u, new.plan_converged, T, R_ext

    return jax.vmap(one)(keys)


@pytest.mark.statistical(p=0.0)
@pytest.mark.parametrize("variant,at_eta", [
    ("paper", 0.4), ("colosseum", 1.0),  # the default profile: both variants, kept and redrawn posterior rows
    pytest.param("paper", 0.0, marks=pytest.mark.nightly), pytest.param("paper", 1.0, marks=pytest.mark.nightly),
    pytest.param("colosseum", 0.0, marks=pytest.mark.nightly),
    pytest.param("colosseum", 0.4, marks=pytest.mark.nightly),
])
def test_plan_is_the_optimum_of_the_dense_extended_mdp_for_every_key(variant, at_eta):
    # For each of 48 keys on each of 3 random count tables (deterministic: the plan and the dense model share their
    # draws, p = 0): the plan's values lie within policy iteration's guarantee of the float64 optimum of the dense
    # extended MDP (0 <= V* - u <= eps / (1 - gamma), eps = 1e-5 (1 + max|u|), plus float32 error eta_f = 2e-4
    # max|V*|, as in test_psrl_continuous_plan), and its real action is the optimum's at every state whose optimal
    # real action leads the others by more than twice that (so the plan's Q, within gamma (eps / (1 - gamma) +
    # eta_f) of Q*, cannot reorder them). Enough states are decided by that margin that the check is not vacuous.
    g = rng(57)
    decided = total = 0
    for table in range(3):
        counts = _random_counts(g, at_eta)
        mu = g.uniform(0.0, 1.0, (4, 2))
        _, state = _state(counts, mu, reward_count=4.0)
        Q, u, converged, T, R_ext = _plans_and_dense(jax.random.split(key(570 + table), 48), state, variant)
        assert bool(jnp.all(converged))
        mask = np.repeat(ACTION_MASK, state.hparams.max_psi)
        for i in range(Q.shape[0]):
            Tr = np.asarray(T[i], np.float64)[np.ix_(REAL_S, np.arange(T.shape[2]), REAL_S)]
            R = np.where(mask, np.asarray(R_ext[i], np.float64), -np.inf)[REAL_S]
            V, Qx = numpy_reference.discounted_optimum(Tr, R, GAMMA)
            ui = np.asarray(u[i], np.float64)[REAL_S]
            eps, eta_f = 1e-5 * (1 + np.abs(ui).max()), 2e-4 * np.abs(V).max()
            assert np.all(V - ui >= -eta_f) and np.all(V - ui <= eps / (1 - GAMMA) + eta_f), (V, ui)
            q_real = np.max(Qx.reshape(4, A, -1), axis=-1)[:, REAL_A]  # [4 states, 2 real actions]
            margin = np.abs(q_real[:, 0] - q_real[:, 1])
            sure = margin > 2 * (eps / (1 - GAMMA) + eta_f)
            plan_action = np.argmax(np.asarray(Q[i])[REAL_S][:, REAL_A], axis=-1)
            np.testing.assert_array_equal(plan_action[sure], np.argmax(q_real, axis=-1)[sure])
            decided, total = decided + int(sure.sum()), total + 4
    # The colosseum variant gives extended action (a, k) the reward of real action (a psi + k) mod A, so both real
    # actions hold candidates with either reward and tie far more often (about 40% decided on these tables; the
    # paper's variant about three quarters, 431 of 576 at at_eta 0).
    assert decided >= (0.7 if variant == "paper" else 0.3) * total, (decided, total)


# ---------------------------------------------------------------------------------------------------------------
# The same distribution of plans as an independent implementation
# ---------------------------------------------------------------------------------------------------------------


def _numpy_plans(counts: np.ndarray, mu: np.ndarray, reward_count: float, n: int, g: np.random.Generator,
                 psi: int = 3) -> np.ndarray:
    """``n`` independent plans of Agrawal & Jia's optimistic PSRL on the 4 real states, in numpy and float64, written
    from the paper's definitions (agents/psrl_continuous.py's docstring): the real action of the optimal extended
    action per state, ``[n, 4]``.

    Rewards: ``tau ~ Gamma(n_r / 2, rate n_r / 2)``, ``R ~ N(mu, 1 / (n_r tau))``, ``n_r = 1 + reward_count``, one draw
    per pair shared by its candidates. Candidates of a pair with ``N < eta = 5`` visits: ``p^- = p_hat - min(sqrt(3
    p_hat ln(4 S) / N') + 3 ln(4 S) / N', p_hat)`` plus the missing mass on a uniformly drawn real state, per pair and
    candidate; at ``eta``: ``Dirichlet(1 / S + N(s, a, .))``. Optimum by policy iteration on all draws at once."""
    Sr, Ar = counts.shape[:2]
    N = counts.sum(-1)
    nr = 1.0 + reward_count
    tau = g.gamma(nr / 2, 2 / nr, (n, Sr, Ar))
    R = mu + g.standard_normal((n, Sr, Ar)) / np.sqrt(nr * tau)
    n1 = np.maximum(N, 1)[..., None]
    p_hat = counts / n1
    L = np.log(4 * Sr)
    p_minus = p_hat - np.minimum(np.sqrt(3 * p_hat * L / n1) + 3 * L / n1, p_hat)
    z = g.integers(0, Sr, (n, Sr, Ar, psi))
    P = p_minus[None, :, :, None, :] + (1 - p_minus.sum(-1))[None, :, :, None, None] * np.eye(Sr)[z]
    for s in range(Sr):
        for a in range(Ar):
            if N[s, a] >= 5:
                P[:, s, a] = g.dirichlet(1.0 / Sr + counts[s, a], (n, psi))
    # Extended MDP: action j = a psi + k.
    T = P.reshape(n, Sr, Ar * psi, Sr)
    Rx = np.repeat(R, psi, axis=-1)
    rows = np.arange(n)[:, None]
    states = np.arange(Sr)[None, :]
    pi = np.argmax(Rx, axis=-1)
    for _ in range(100):
        V = np.linalg.solve(np.eye(Sr) - GAMMA * T[rows, states, pi], Rx[rows, states, pi][..., None])[..., 0]
        Q = Rx + GAMMA * np.einsum("nsjt,nt->nsj", T, V)
        better = Q.max(-1) > Q[rows, states, pi] + 1e-12 * (1 + np.abs(V).max(-1, keepdims=True))
        if not better.any():
            break
        pi = np.where(better, Q.argmax(-1), pi)
    assert not better.any()
    return np.argmax(Q.reshape(n, Sr, Ar, psi).max(-1), axis=-1)


@functools.partial(jax.jit, static_argnames="variant")
def _plan_actions(keys, state, variant="paper"):
    agent = get("psrl_continuous", variant)
    Q = jax.vmap(lambda k: agent.plan(k, state).Q)(keys)
    return jnp.argmax(Q[:, REAL_S][:, :, REAL_A], axis=-1)


# Counts chosen so that both real actions are optimal in a good share of the draws at every state, with pairs below
# and at eta (rows of jumps, rows with mass at observed states, Dirichlet rows).
COUNTS = np.array([
    [[0, 0, 0, 0], [1, 1, 0, 0]],
    [[0, 2, 1, 0], [3, 0, 3, 2]],
    [[2, 0, 0, 3], [0, 0, 1, 1]],
    [[0, 1, 0, 2], [1, 3, 0, 0]],
])
MU = np.array([[0.2, 0.3], [0.5, 0.45], [0.4, 0.3], [0.9, 0.8]])
N_PLANS = 6000


@pytest.mark.statistical(p=4e-7)
def test_plans_have_the_distribution_of_an_independent_implementation():
    # Per real state, the share of plans whose real action is 0: the agent's (N_PLANS keys) against the numpy
    # implementation's (N_PLANS draws of its own). Under equal distributions the difference of the two counts is a sum
    # of N_PLANS independent terms X_i - Y_i in [-1, 1] of mean 0 and variance 2 p (1 - p) <= 1/2, so Bernstein's
    # inequality bounds it at false-failure 1e-7 per state (stat_checks.Checks.bernstein_mean with the variance's
    # bound): 4 checks, p <= 4e-7. The plans are float32 policy iteration to eps = 1e-5 (1 + max|V|) against
    # float64's optimum: they can differ only at draws whose two real actions are that close, a probability far
    # below the test's resolution (a difference of about 0.08 in the share).
    _, state = _state(COUNTS, MU, reward_count=4.0)
    ours = np.asarray(_plan_actions(jax.random.split(key(571), N_PLANS), state))
    theirs = _numpy_plans(COUNTS, MU, 4.0, N_PLANS, rng(572))
    checks = Checks()
    for s in range(4):
        share_ours, share_theirs = np.mean(ours[:, s] == 0), np.mean(theirs[:, s] == 0)
        checks.bernstein_mean(share_ours - share_theirs, N_PLANS, 0.0, 0.5, 1.0,
                              f"state {s}: share of action 0, agent {share_ours:.3f}, numpy {share_theirs:.3f}")
    assert checks.false_failure_bound() <= 4e-7
