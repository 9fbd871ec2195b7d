"""Optimistic PSRL (continuous): the structured extended-MDP plan against the dense extended MDP of the same draws.

The plan never builds the ``[max_psi, S, A, S]`` candidate kernels (agents/psrl_continuous.py); these tests
materialise them from the same draws (``candidate_kernels``) and solve the explicit extended MDP with
``dp.policy_iteration`` (the planner the agent used before), with a float64 solver of their own, and with
``dp.optimal_gain`` for the average-reward branch.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import agents.extended_policy_iteration as epi
import agents.psrl_continuous as pc
import jaxmdp
import numpy_reference
from agents import estimated_model as em
from agents import get
from agents.posteriors import normal_gamma_sample
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment.agent_interface import spec_of
from stat_checks import Checks, key

# S = 7 padded to 8 with a padded state in the middle (index 3), A = 3 with action 2 padded; psi = 3 of max_psi = 4.
S, A = 8, 3
STATE_MASK = np.array([True, True, True, False, True, True, True, True])
ACTION_MASK = np.array([True, True, False])
N_KEYS = 3


def _state(variant, case, discount=0.99, seed=0):
    """A state with random counts on the real pairs: ``case`` none / some / all of them at ``eta = 5``."""
    agent = get("psrl_continuous", variant)
    rng = np.random.default_rng(seed)
    mdp = jaxmdp.custom_mdp(np.full((S, A, S), 1.0 / S), R=np.zeros((S, A)))
    spec = spec_of(mdp, 500_000).replace(state_mask=jnp.asarray(STATE_MASK), action_mask=jnp.asarray(ACTION_MASK))
    hp = agent.default_hparams.replace(max_psi=4, psi_weight=0.08, eta_weight=0.0, discount=discount, plan_tol=1e-5)
    state = agent.init(jax.random.key(0), spec, hp)
    real_pairs = STATE_MASK[:, None] & ACTION_MASK[None, :]
    at_eta = {"none": np.zeros((S, A), bool), "all": np.ones((S, A), bool),
              "some": rng.random((S, A)) < 0.4}[case] & real_pairs
    # Pairs below eta: 0 to 4 visits; pairs at eta: 5 to 12. Next states uniform among the real ones.
    visits = np.where(at_eta, rng.integers(5, 13, (S, A)), rng.integers(0, 5, (S, A))) * real_pairs
    p = STATE_MASK / STATE_MASK.sum()
    counts = np.stack([[rng.multinomial(visits[s, a], p) for a in range(A)] for s in range(S)])
    counts = jnp.asarray(counts, jnp.int32)
    mu = jnp.asarray(rng.uniform(0, 1, (S, A)), jnp.float32)
    state = state.replace(successors=em.with_dense_counts(state.successors, counts),
                          schedule=state.schedule.replace(visits=counts.sum(-1)),
                          rewards=state.rewards.replace(mu=mu), u=jnp.asarray(rng.uniform(0, 3, S), jnp.float32))
    assert int(state.constants.psi) == 3 and float(state.constants.eta) == 5.0
    n_eta = int(jnp.sum((state.schedule.visits >= 5) & STATE_MASK[:, None] & ACTION_MASK[None, :]))
    assert {"none": n_eta == 0, "some": 0 < n_eta < 14, "all": n_eta == 14}[case], n_eta
    return agent, state


@functools.partial(jax.jit, static_argnames=("variant", "keep_limit"))
def _dense(k, state, variant, keep_limit=pc.KEEP_LIMIT):
    """The explicit extended MDP of the draws that plan(k, state) makes (same key split). Jitted: called eagerly, the
    ``lax.map`` loops inside the draws compiled again at every call (their bodies are new closures each time), 180
    compilations and about half of this file's time."""
    k_r, k_p = jax.random.split(k)
    R = normal_gamma_sample(k_r, state.rewards)
    P = pc.candidate_kernels(k_p, state, variant=variant, keep_limit=keep_limit)
    T, Rx, mask = pc.extended_mdp(R, P, state.action_mask)
    if variant == "colosseum":
        Rx = pc.colosseum_extended_rewards(R, state.constants.psi, state.hparams.max_psi, state.action_mask)
    return T, Rx, mask


@jax.jit
def _dense_policy_iteration(T, R, mask, u, gamma):
    """The planner before the structured one: dp.policy_iteration on the dense extended MDP, warm-started greedy."""
    start = dp.greedy(dp.q_values(T, u, gamma, R), mask)
    return dp.policy_iteration(T, gamma, rewards=R, policy=start)


@functools.partial(jax.jit, static_argnames=("variant", "keep_limit"))
def _overflow(k, state, variant, keep_limit=pc.KEEP_LIMIT):
    """Whether the draws of ``k`` have more pairs at ``eta`` than they keep (jitted, as :func:`_dense`)."""
    return pc.draws(k, state, variant=variant, keep_limit=keep_limit).overflow


@jax.jit
def _optimal_gain(T, R):
    """The optimal gain of the explicit extended MDP (``dp.optimal_gain``, tight tolerance); jitted, as its loops
    compiled again at every eager call."""
    return dp.optimal_gain(T, rewards=R, tol=2e-6, max_iter=1_000_000)


def _float64_optimum(T, R, mask, gamma):
    """``V*`` of the dense model in float64 (:func:`numpy_reference.discounted_optimum`)."""
    return numpy_reference.discounted_optimum(T, np.where(mask, np.asarray(R, np.float64), -np.inf), gamma)[0]


CASES = [(v, c) for v in ("paper", "colosseum") for c in ("none", "some", "all")]


@pytest.mark.statistical(p=0.0)
@pytest.mark.parametrize("jump_states", [pc.JUMP_STATES, 5, 2, (2, 5)])
@pytest.mark.parametrize("variant,case", CASES)
def test_discounted_plan_equals_policy_iteration_on_the_dense_extended_mdp(variant, case, jump_states):
    # For every key (a deterministic comparison, p = 0): the structured plan's values equal those of the dense
    # planner on the same draws to float32 precision, and lie within policy iteration's guarantee of the float64
    # optimum (0 <= V* - V <= eps / (1 - gamma), eps = 1e-5 (1 + max|V|), plus float32 evaluation error, see
    # test_psrl_continuous.test_discounted_planning_matches_exact_solution).
    # jump_states below S = 8: the evaluations eliminate the jumping states when at most that many others remain (5:
    # often in case "none", where every pair is below eta with at most 4 visits, so p^- = 0), else solve the whole
    # chain (2: mostly); (2, 5): a system of 2 first, then of 5, then the whole chain.
    # The two float32 planners' values differ by their solves' rounding, amplified up to 1 / (1 - gamma) = 100 times:
    # measured against a float64 solve of the same final policy (paper, "all", jump_states 5, second key), the
    # structured plan's values err by 1.8e-4 and the dense planner's by 5.5e-4, at |V| = 309; hence 4e-6 (1 + max|V|).
    agent, state = _state(variant, case)
    plan = jax.jit(functools.partial(agent.plan, jump_states=jump_states))
    gamma, K = 0.99, state.hparams.max_psi
    for k in jax.random.split(key(21), N_KEYS):
        new = plan(k, state)
        assert bool(new.plan_converged)
        T, R, mask = _dense(k, state, variant)
        ref = _dense_policy_iteration(T, R, mask, state.u, gamma)
        scale = 1 + float(np.abs(ref.V).max())
        np.testing.assert_allclose(new.u, ref.V, rtol=0, atol=4e-6 * scale)
        Q_ref = np.asarray(ref.Q).reshape(S, A, K).max(-1)
        np.testing.assert_allclose(new.Q, Q_ref, rtol=0, atol=4e-6 * scale)
        V = _float64_optimum(T, R, mask, gamma)[STATE_MASK]
        u = np.asarray(new.u, np.float64)[STATE_MASK]
        eps, eta = 1e-5 * (1 + np.abs(u).max()), 2e-4 * np.abs(V).max()
        assert np.all(V - u >= -eta) and np.all(V - u <= eps / (1 - gamma) + eta), (V, u)


@pytest.mark.statistical(p=0.0)
@pytest.mark.parametrize("variant,case", CASES)
def test_average_reward_plan_is_gain_optimal_in_the_dense_extended_mdp(variant, case):
    # Relative value iteration on the structured backup: a converged plan's gain bounds (max_a Q - u, tolerance
    # plan_tol = 1e-5) contain the optimal gain of the explicit extended MDP; its greedy real action is that of an
    # optimal extended action of the same gain. Every key (p = 0).
    agent, state = _state(variant, case, discount=1.0)
    plan = jax.jit(agent.plan)
    for k in jax.random.split(key(22), N_KEYS):
        new = plan(k, state)
        if not bool(new.plan_converged):
            assert int(new.plan_iterations) == state.hparams.plan_max_iter
            continue
        T, R, mask = _dense(k, state, variant)
        # Padded states are absorbing in neither model's sense; drop them (no real state reaches them).
        real = np.flatnonzero(STATE_MASK)
        Tr = np.asarray(T)[np.ix_(real, np.arange(T.shape[1]), real)]
        ref = _optimal_gain(jnp.asarray(Tr), jnp.asarray(np.asarray(R)[real]))
        assert bool(ref.converged)
        d = (np.asarray(new.Q).max(-1) - np.asarray(new.u))[real]
        # Both gains are float32 differences of values as large as |u|: their rounding grows with it (a draw with
        # rewards up to 67 and |u| up to 79 is 4.4e-5 off, about six float32 ulps of 79).
        np.testing.assert_allclose(d, float(ref.gain), atol=3e-5 + 1e-6 * float(np.abs(np.asarray(new.u)).max()))


@pytest.mark.parametrize("keep_limit", [pc.KEEP_LIMIT, 0])
def test_chosen_rows_and_expectations_agree_at_any_states(keep_limit):
    # A policy's rows built at a subset of states (as the evaluation's eliminated system asks for them) are the rows of
    # the whole chain at those states, and the improvement step's expectations of the current policy are those rows
    # times V: kept posterior rows, and (keep_limit 0: more pairs at eta than kept) rows drawn again from the keys.
    _, state = _state("paper", "some", seed=4)
    gamma = jnp.asarray(0.99, jnp.float32)

    @jax.jit
    def check(k, V, s):
        R_ext, d = pc.extended_draws(k, state, keep_limit=keep_limit)
        _, pi = epi._greedy(d, R_ext, V, gamma, state.action_mask)
        whole = epi._chosen_rows(d, pi, jnp.arange(S))
        return d.overflow, jnp.any(d.posterior), whole, epi._chosen_rows(d, pi, s), epi._chosen_expectations(d, pi, V)

    V = jax.random.uniform(key(26), (S,), jnp.float32, 0.0, 10.0)
    s = jnp.array([6, 1, 4, 1], jnp.int32)
    overflow, any_posterior, whole, part, expected = check(key(27), V, s)
    assert bool(any_posterior) and bool(overflow) == (keep_limit == 0)
    np.testing.assert_array_equal(part, whole[np.asarray(s)])
    np.testing.assert_allclose(expected, np.asarray(whole, np.float64) @ np.asarray(V, np.float64), rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(np.asarray(whole).sum(-1)[STATE_MASK], 1.0, atol=1e-5)


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_lean_draws_plan_as_the_full_ones_when_no_pair_is_at_eta(variant):
    # A plan with no pair at eta runs on lean draws (no kept rows, no posterior branches): the same candidates from the
    # same key, bit for bit, and the same policy iteration (values to float32 rounding, the same greedy actions); the
    # plan's own result is that of the full draws.
    agent, state = _state(variant, "none", seed=6)
    assert not bool(jnp.any(epi.at_eta(state)))  # so that the plan runs lean
    gamma = jnp.asarray(0.99, jnp.float32)

    @jax.jit
    def both(k):
        out = []
        for lean in (False, True):
            R_ext, d = pc.extended_draws(k, state, variant=variant, lean=lean)
            res = epi.extended_policy_iteration(d, R_ext, gamma, state.u, state.action_mask)
            out.append((R_ext, d.z, d.p_minus, d.missing, d.kept.shape, res.V, res.Q))
        return out

    plan = jax.jit(agent.plan)
    for k in jax.random.split(key(28), N_KEYS):
        full, lean = both(k)
        for x, y in zip(full[:4], lean[:4]):
            np.testing.assert_array_equal(x, y)
        assert full[4][1] >= 1 and lean[4] == (state.hparams.max_psi, 0, S)
        scale = 1 + float(np.abs(full[5]).max())
        np.testing.assert_allclose(lean[5], full[5], rtol=0, atol=1e-6 * scale)
        np.testing.assert_allclose(lean[6], full[6], rtol=0, atol=1e-6 * scale)
        np.testing.assert_array_equal(np.asarray(lean[6]).argmax(-1), np.asarray(full[6]).argmax(-1))
        new = plan(k, state)
        np.testing.assert_allclose(new.u, full[5], rtol=0, atol=1e-6 * scale)


# Nightly; a corner (one kept pair) of test_discounted_plan_equals_policy_iteration_on_the_dense_extended_mdp.
@pytest.mark.nightly
@pytest.mark.statistical(p=0.0)
@pytest.mark.parametrize("variant", ["paper", pytest.param("colosseum", marks=pytest.mark.nightly)])
def test_more_pairs_at_eta_than_kept(variant):
    """M = 1 kept pair (``keep_limit=0``), fewer than the pairs at eta: the plan uses the draws of every pair (redrawn
    at each backup), and still solves the dense extended MDP of its draws (discounted: dp.policy_iteration; average
    reward: the optimal gain), for every key (p = 0). Batched with a member without pairs at eta (kept path), each
    member plans as alone."""
    agent = get("psrl_continuous", variant)
    plan = jax.jit(functools.partial(agent.plan, keep_limit=0))  # one program for both discounts (a traced hparam)
    plan_both = jax.jit(jax.vmap(plan))
    for discount in (0.99, 1.0):
        state = _state(variant, "some", discount=discount, seed=4)[1]
        assert bool(_overflow(jax.random.key(0), state, variant, keep_limit=0))
        for k in jax.random.split(key(24), 2):
            new = plan(k, state)
            T, R, mask = _dense(k, state, variant, keep_limit=0)
            if discount < 1:
                ref = _dense_policy_iteration(T, R, mask, state.u, discount)
                np.testing.assert_allclose(new.u, ref.V, rtol=0, atol=2e-6 * (1 + float(np.abs(ref.V).max())))
            elif bool(new.plan_converged):
                real = np.flatnonzero(STATE_MASK)
                Tr = jnp.asarray(np.asarray(T)[np.ix_(real, np.arange(T.shape[1]), real)])
                ref = _optimal_gain(Tr, jnp.asarray(np.asarray(R)[real]))
                np.testing.assert_allclose((np.asarray(new.Q).max(-1) - np.asarray(new.u))[real], float(ref.gain),
                                           atol=3e-5)
        other = _state(variant, "none", discount=discount, seed=5)[1]
        keys = jax.random.split(key(25), 2)
        batch = jax.tree.map(lambda *x: jnp.stack(x), state, other)
        both = plan_both(keys, batch)
        for i, member in enumerate((state, other)):
            alone = plan(keys[i], member)
            np.testing.assert_allclose(both.u[i], alone.u, rtol=1e-6, atol=1e-6)
            np.testing.assert_array_equal(both.Q[i].argmax(-1), alone.Q.argmax(-1))


@pytest.mark.statistical(p=1.4e-6)
@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_missing_mass_goes_to_a_uniform_real_state(variant):
    # 4000 keys. The state receiving the missing mass is never padded (state 3, in the middle: the draw maps an
    # index among the real states to its state), and each real state's count is Binomial(4000, 1/7) for two
    # independent draws (paper: slot 0 of pair (0, 0) and slot 1 of pair (5, 1)) or one (colosseum: slot 0's state,
    # shared by all pairs). 14 or 7 binomial checks at 1e-7 each: false-failure probability <= 1.4e-6.
    _, state = _state(variant, "none")
    z = np.asarray(jax.jit(jax.vmap(lambda k: pc.draws(k, state, variant=variant).z))(
        jax.random.split(key(23), 4000)))  # [n, max_psi, S, A]
    assert np.all(STATE_MASK[z])  # never a padded state, in any slot or pair
    samples = [z[:, 0, 0, 0], z[:, 1, 5, 1]] if variant == "paper" else [z[:, 0, 0, 0]]
    checks = Checks()
    for x in samples:
        counts = np.bincount(x, minlength=S)
        for t in np.flatnonzero(STATE_MASK):
            checks.binomial(int(counts[t]), x.size, 1 / 7, f"state {t}")
    if variant == "colosseum":
        assert np.all(z == z[:, :, :1, :1])  # one state per slot, shared by all pairs
    assert checks.n == 7 * len(samples)


def _banded_state(variant, case, bandwidth, seed=0):
    """A state whose MDP has a band order (a random permutation; transitions within 2 positions of it), ``eta = 10 S
    = 70``: the pairs of five states visited 35-69 times (not at ``eta``; action 0 on one successor, action 1 on two at
    odds 9 : 1, so that ``p^- > 0`` on one slot), the other pairs 0-4 times (jump rows); case "some": a few pairs
    visited 70-89 times (at ``eta``). The agent's band order is the MDP's with the given ``bandwidth`` (1: some
    observed successors lie outside it)."""
    agent = get("psrl_continuous", variant)
    rng = np.random.default_rng(seed)
    real = np.flatnonzero(STATE_MASK)
    order = rng.permutation(S)
    pos = np.argsort(order)
    mdp = jaxmdp.custom_mdp(np.full((S, A, S), 1.0 / S), R=np.zeros((S, A)))
    spec = spec_of(mdp, 500_000, jnp.asarray(order, jnp.int32), bandwidth).replace(
        state_mask=jnp.asarray(STATE_MASK), action_mask=jnp.asarray(ACTION_MASK))
    hp = agent.default_hparams.replace(max_psi=4, psi_weight=0.08, eta_weight=1.0, discount=0.99, plan_tol=1e-5)
    state = agent.init(jax.random.key(0), spec, hp)
    counts = np.zeros((S, A, S), np.int64)
    visited = rng.choice(real, size=5, replace=False)  # all their pairs, so that their chosen rows have p^- > 0
    for s in real:
        near = [t for t in real if abs(pos[t] - pos[s]) <= 2]
        for a in np.flatnonzero(ACTION_MASK):
            n = rng.integers(35, 70) if s in visited else rng.integers(0, 5)
            if case == "some" and rng.random() < 0.15:
                n = rng.integers(70, 90)
            if s in visited:
                succ, odds = rng.choice(near, size=2, replace=False), [0.9, 0.1] if a else [1.0, 0.0]
            else:
                succ, odds = real, None
            np.add.at(counts[s, a], rng.choice(succ, size=n, p=odds), 1)
    counts = jnp.asarray(counts, jnp.int32)
    state = state.replace(successors=em.with_dense_counts(state.successors, counts),
                          schedule=state.schedule.replace(visits=counts.sum(-1)),
                          rewards=state.rewards.replace(mu=jnp.asarray(rng.uniform(0, 1, (S, A)), jnp.float32)),
                          u=jnp.asarray(rng.uniform(0, 3, S), jnp.float32))
    assert float(state.constants.eta) == 70.0 and state.successors.bandwidth == bandwidth
    assert bool(jnp.any(epi.at_eta(state))) == (case == "some")
    return agent, state


@functools.partial(jax.jit, static_argnames=("variant", "lean"))
def _first_policy(k, state, variant, lean):
    """The plan's first policy iteration step with key ``k`` (discounted, 0.99): its draws, its policy (greedy on one
    backup of ``state.u``), the policy's rows, the banded evaluations of sizes 1, 2, 8 and ``S`` (``(V, fits)``),
    whether the jump elimination of size 2 fits, and whether every ``p^-`` lies in the band."""
    gamma = jnp.asarray(0.99, jnp.float32)
    R_ext, d = pc.extended_draws(k, state, variant=variant, lean=lean)
    _, pi = epi._greedy(d, R_ext, state.u, gamma, state.action_mask)
    banded = {size: epi._banded_values(d, pi, gamma, size) for size in (1, 2, 8, S)}
    rows = functools.partial(epi._chosen_rows, d, pi)
    jump2 = dp.discounted_jump_chain_values(rows, pi.reward, gamma, pi.jump, 2)[1]
    return d, pi, rows(jnp.arange(S)), banded, jump2, d.p_minus_kernel().in_band()


def _chosen(d, pi):
    """Host-side facts of policy ``pi``'s rows: their ``p^-`` ``[S, K]``, whether one is a posterior row, and the
    states their missing mass goes to."""
    s, a = np.arange(S), np.asarray(pi.action)
    targets = np.asarray(d.z)[np.asarray(pi.k), s, a][np.asarray(d.missing)[s, a] > 0]
    return np.asarray(d.p_minus)[s, a], bool(np.any(np.asarray(d.posterior)[s, a])), np.unique(targets)


@pytest.mark.statistical(p=0.0)
@pytest.mark.parametrize("case", ["none", "some"])
@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_banded_evaluation_is_the_chosen_chains_values(variant, case):
    # For every key (p = 0): the banded evaluation of the plan's first policy, in the MDP's band order, equals a
    # float64 solve of the chosen rows (_chosen_rows) to 5e-6 max|V| when no chosen row is a posterior one, and it
    # fits exactly when no chosen row is a posterior one and at most its size of states are jumped to. Its premise,
    # every pair's p^- in the band (Draws.p_minus_kernel().in_band(), the plan's check), holds at bandwidth 2 and
    # not at bandwidth 1 (an observed successor 2 positions away).
    for bandwidth in (2, 1):
        _, state = _banded_state(variant, case, bandwidth)
        for k in jax.random.split(key(31), 4):
            d, pi, rows, banded, _, in_band = _first_policy(k, state, variant, case == "none")
            pos = np.argsort(np.asarray(d.order))
            gaps = np.abs(pos[:, None, None] - pos[np.asarray(d.slot_states)])
            assert bool(in_band) == bool(np.all((np.asarray(d.p_minus) == 0) | (gaps <= bandwidth)))
            assert bool(in_band) == (bandwidth == 2)
            p_minus, posterior, targets = _chosen(d, pi)
            for size, (_, fits) in banded.items():
                assert bool(fits) == (not posterior and len(targets) <= size)
            if bandwidth == 2 and case == "none":
                assert not posterior and np.any(p_minus > 0)  # the banded values are checked, with a non-empty B
            if bandwidth == 2 and not posterior:
                expected = np.linalg.solve(np.eye(S) - 0.99 * np.asarray(rows, np.float64), np.asarray(pi.reward))
                np.testing.assert_allclose(banded[S][0], expected, rtol=0, atol=5e-6 * np.abs(expected).max())


def _banded_size(first):
    """The size of the banded evaluation that the plan's first evaluation is (``jump_states=2, band_targets=(2, 8)``):
    2 or 8, or 0 when it is another one, from :func:`_first_policy`'s result."""
    _, _, _, banded, jump2, in_band = first
    if bool(jump2) or not bool(in_band):
        return 0
    return next((size for size in (2, 8) if bool(banded[size][1])), 0)


@pytest.mark.statistical(p=0.0)
@pytest.mark.parametrize("case,bandwidth", [("none", 2), ("some", 2), ("none", 1)])
@pytest.mark.parametrize("variant", ["paper", pytest.param("colosseum", marks=pytest.mark.nightly)])
def test_banded_plan_equals_policy_iteration_on_the_dense_extended_mdp(variant, case, bandwidth):
    # As test_discounted_plan_equals_policy_iteration_on_the_dense_extended_mdp, for a state with a band order:
    # jump_states 2 leaves most evaluations to the banded one (band_targets 2, then 8), the rest to the whole chain.
    # Case "none": some key's first evaluation is a banded one; case "some": some key's first policy
    # chooses a posterior row, which no banded evaluation takes; bandwidth 1: an observed successor lies outside the
    # band, so the fallback is what is checked.
    agent, state = _banded_state(variant, case, bandwidth)
    plan = jax.jit(functools.partial(agent.plan, jump_states=2, band_targets=(2, 8)))
    banded, posterior_rows = [], []
    for k in jax.random.split(key(32), N_KEYS):
        new = plan(k, state)
        assert bool(new.plan_converged)
        T, R, mask = _dense(k, state, variant)
        ref = _dense_policy_iteration(T, R, mask, state.u, 0.99)
        scale = 1 + float(np.abs(ref.V).max())
        np.testing.assert_allclose(new.u, ref.V, rtol=0, atol=4e-6 * scale)
        np.testing.assert_allclose(new.Q, np.asarray(ref.Q).reshape(S, A, -1).max(-1), rtol=0, atol=4e-6 * scale)
        first = _first_policy(k, state, variant, case == "none")
        banded.append(_banded_size(first))
        posterior_rows.append(_chosen(*first[:2])[1])
        assert not (banded[-1] and posterior_rows[-1])
    if bandwidth == 1:
        assert not any(banded)
    elif case == "none":  # the paper's candidates jump to more states than two; the reference's share them per slot
        assert (8 if variant == "paper" else 2) in banded
    assert any(posterior_rows) == (case == "some")


@pytest.mark.statistical(p=0.0)
def test_banded_plans_batched_as_alone():
    # Under vmap (the runner's planning slots) the evaluations' skips run for every member when one needs them: a
    # member whose first evaluation is banded and one whose first policy chooses a posterior row (case "some", so
    # not banded) plan as alone.
    plan = jax.jit(functools.partial(get("psrl_continuous").plan, jump_states=2, band_targets=(2, 8)))
    members = [_banded_state("paper", case, 2, seed=seed)[1] for case, seed in (("none", 1), ("some", 2))]
    keys = jax.random.split(key(33), 2)
    assert _banded_size(_first_policy(keys[0], members[0], "paper", True)) == 8
    assert _chosen(*_first_policy(keys[1], members[1], "paper", False)[:2])[1]
    batch = jax.tree.map(lambda *x: jnp.stack(x), *members)
    both = jax.jit(jax.vmap(plan))(keys, batch)
    for i, member in enumerate(members):
        alone = plan(keys[i], member)
        np.testing.assert_allclose(both.u[i], alone.u, rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(both.Q[i].argmax(-1), alone.Q.argmax(-1))
