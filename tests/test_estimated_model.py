"""The estimated kernel on observed next states (agents.estimated_model) against dense numpy computations: counts of a
transition stream, expectations and policy matrices, and the discounted greedy policy by enumerating every
deterministic policy; UCRL2's policy estimate against the dense route it replaced."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmdp
from agents import estimated_model as em
from agents import psrl_continuous, ucrl2
from agents.extended_value_iteration import confidence_box
from agents.posteriors import dirichlet_mean, normal_gamma_mean
from agents.tabular_common import copy_action_zero
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment import runner
from jaxmdp.experiment.agent_interface import Transition, spec_of
from random_play import played


def _stream(rng, n, S, A, K):
    """``n`` transitions whose next states come from ``K`` fixed candidates per pair (so ``K`` slots suffice)."""
    cand = np.stack([rng.choice(S, size=K, replace=False) for _ in range(S * A)]).reshape(S, A, K)
    s, a = rng.integers(0, S, n), rng.integers(0, A, n)
    return s, a, cand[s, a, rng.integers(0, K, n)]


def _record_all(table, s, a, s2):
    step = jax.jit(em.record)
    for x in zip(s, a, s2):
        table = step(table, *map(jnp.int32, x))
    return table


def test_record_counts_every_transition_in_first_seen_slots():
    rng = np.random.default_rng(0)
    S, A, K = 7, 3, 4
    s, a, s2 = _stream(rng, 400, S, A, K)
    table = _record_all(em.empty_counts(S, A, K), s, a, s2)
    dense = np.zeros((S, A, S), np.int64)
    np.add.at(dense, (s, a, s2), 1)
    np.testing.assert_array_equal(em.dense_counts(table), dense)
    assert not bool(table.overflowed)
    for i, j in itertools.product(range(S), range(A)):  # slots in order of first observation, then empty
        seen = s2[(s == i) & (a == j)]
        first = list(dict.fromkeys(seen.tolist()))
        n = len(first)
        assert np.asarray(table.states[i, j, :n]).tolist() == first
        assert np.all(np.asarray(table.counts[i, j, :n]) > 0) and np.all(np.asarray(table.counts[i, j, n:]) == 0)


def test_record_with_count_false_leaves_the_table_as_it_is():
    """A skipped transition changes nothing: not the counts, not the slots' order, not the overflow flag (even for a
    next state that does not fit); counted, that next state overflows the full pair."""
    rng = np.random.default_rng(2)
    S, A, K = 5, 2, 2
    s, a, s2 = _stream(rng, 60, S, A, K)
    table = _record_all(em.empty_counts(S, A, K), s, a, s2)
    skip = jax.jit(em.record)
    full = np.flatnonzero(np.asarray(table.counts[0, 0]) > 0).size == K
    assert full  # pair (0, 0) has met both its next states: a third one overflows when counted
    new = next(x for x in range(S) if x not in np.asarray(table.states[0, 0]).tolist())
    for x in (int(table.states[0, 0, 0]), new):  # a next state the pair has met, and one it has not
        jax.tree.map(np.testing.assert_array_equal, skip(table, 0, 0, x, False), table)
    counted = skip(table, 0, 0, new, True)
    assert bool(counted.overflowed) and not bool(table.overflowed)
    np.testing.assert_array_equal(counted.counts, table.counts)


def test_with_dense_counts_holds_the_same_counts_in_index_order():
    rng = np.random.default_rng(5)
    S, A, K = 7, 3, 4
    s, a, s2 = _stream(rng, 400, S, A, K)
    recorded = _record_all(em.empty_counts(S, A, K), s, a, s2)
    dense = em.dense_counts(recorded)
    table = em.with_dense_counts(em.empty_counts(S, A, K), dense)
    np.testing.assert_array_equal(em.dense_counts(table), dense)
    assert not bool(table.overflowed)
    for i, j in itertools.product(range(S), range(A)):  # the observed next states in index order, then empty slots
        seen = np.flatnonzero(np.asarray(dense[i, j]))
        assert np.asarray(table.states[i, j, :seen.size]).tolist() == seen.tolist()
        np.testing.assert_array_equal(table.counts[i, j, :seen.size], np.asarray(dense[i, j])[seen])
        assert np.all(np.asarray(table.counts[i, j, seen.size:]) == 0)
    # One pair with K + 1 next states: flagged, its first K kept.
    more = np.asarray(dense).copy()
    more[2, 1, :K + 1] = np.arange(1, K + 2)
    flagged = em.with_dense_counts(em.empty_counts(S, A, K), more)
    assert bool(flagged.overflowed)
    np.testing.assert_array_equal(flagged.counts[2, 1], np.arange(1, K + 1))


def test_epoch_agent_states_hold_no_dense_table_and_rebuild_the_counts_from_the_slots():
    """What a planning round moves is the agent state (jaxmdp.experiment.planning): UCRL2's and PSRL continuous's
    hold no leaf of ``S A S`` entries (docs/performance.md, Planning rounds), and their ``counts`` (batched: any
    leading axes) is numpy's scatter of the slots."""
    mdp = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=5, p_lazy=0.3, n_starting_states=2)
    spec = spec_of(mdp, 500)
    S, A, K = mdp.n_states, mdp.n_actions, mdp.max_successors
    for agent in (ucrl2.UCRL2, psrl_continuous.PSRL_CONTINUOUS):
        state = agent.init(jax.random.key(0), spec, agent.default_hparams)
        assert max(np.size(x) for x in jax.tree.leaves(state)) == S * A * K < S * A * S
    rng = np.random.default_rng(4)
    states = rng.integers(0, S, (3, S, A, K))
    counts = rng.integers(0, 5, (3, S, A, K))
    want = np.zeros((3, S, A, S), np.int64)
    for b, i, j, k in itertools.product(range(3), range(S), range(A), range(K)):
        want[b, i, j, states[b, i, j, k]] += counts[b, i, j, k]
    table = em.SuccessorCounts(states=jnp.asarray(states, jnp.int32), counts=jnp.asarray(counts, jnp.int32),
                               overflowed=jnp.zeros(3, bool))
    np.testing.assert_array_equal(em.dense_counts(table), want)


@pytest.mark.nightly  # by default: test_psrl_continuous.py's p^- slots test reports overflow
def test_overflow_is_flagged_and_reported_by_the_agents_diagnostics():
    S, A = 4, 1
    table = _record_all(em.empty_counts(S, A, 2), [0, 0, 0, 0], [0, 0, 0, 0], [1, 2, 1, 3])
    assert bool(table.overflowed)
    np.testing.assert_array_equal(table.counts[0, 0], [2, 1])  # the third next state was not counted
    assert not bool(_record_all(em.empty_counts(S, A, None), [0] * 4, [0] * 4, [1, 2, 1, 3]).overflowed)
    # UCRL2 with a spec that understates the successors: the slots miss counts, and the agent reports it (the runner
    # warns of a non-zero diagnostic at the end of a run).
    mdp = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=5, p_lazy=0.3, n_starting_states=2,
                      make_reward_stochastic=True)
    assert mdp.max_successors > 1
    spec = spec_of(mdp, 500).replace(max_successors=1)
    state = ucrl2.UCRL2.init(jax.random.key(0), spec, ucrl2.UCRL2.default_hparams)
    obs, env_state = jaxmdp.reset(jax.random.key(1), mdp)
    for k in jax.random.split(jax.random.key(2), 300):
        a = jax.random.randint(jax.random.fold_in(k, 1), (), 0, mdp.n_actions)
        obs2, env_state, r, term, _, info = jaxmdp.step(k, env_state, a, mdp)
        state = _UPDATE(state, Transition(obs=obs, action=a, reward=r, next_obs=info["final_observation"],
                                          h=env_state.h, terminated=term))
        obs = obs2
    assert bool(state.successors.overflowed)
    assert int(state.counts.sum()) < 300  # transitions lost
    for agent in (ucrl2.UCRL2, psrl_continuous.PSRL_CONTINUOUS):
        fresh = agent.init(jax.random.key(0), spec, agent.default_hparams)
        assert int(agent.diagnostics(fresh)["slots_overflowed"]) == 0
        assert int(agent.diagnostics(fresh.replace(successors=state.successors))["slots_overflowed"]) == 1


_UPDATE = jax.jit(ucrl2.update)


def _random_kernel(rng, S, A, K, n_real):
    """A kernel with ``K`` slots per pair on real states (distinct, some empty) and a uniform part, and its dense
    numpy form built entry by entry."""
    mask = np.arange(S) < n_real
    states = np.stack([rng.choice(n_real, size=K, replace=False) for _ in range(S * A)]).reshape(S, A, K)
    w = rng.random((S, A, K)) * (rng.random((S, A, K)) < 0.7)
    uniform = rng.random((S, A)) * (rng.random((S, A)) < 0.5)
    total = w.sum(-1) + uniform
    total[total == 0] = 1.0
    probs, uniform = w / total[..., None], uniform / total
    uniform[w.sum(-1) == 0] = 1.0
    dense = np.zeros((S, A, S))
    for i, j in itertools.product(range(S), range(A)):
        for k in range(K):
            dense[i, j, states[i, j, k]] += probs[i, j, k]
        dense[i, j, :n_real] += uniform[i, j] / n_real
    kernel = em.SparseKernel(jnp.asarray(states, jnp.int32), jnp.asarray(probs, jnp.float32),
                             jnp.asarray(uniform, jnp.float32), jnp.asarray(mask))
    return kernel, dense


def test_expectations_and_policy_matrix_match_the_dense_kernel():
    rng = np.random.default_rng(1)
    S, A, K = 9, 3, 3
    kernel, dense = _random_kernel(rng, S, A, K, n_real=7)
    np.testing.assert_allclose(dense.sum(-1), 1.0, atol=1e-12)
    V = rng.normal(size=S) * 5
    np.testing.assert_allclose(em.expected_next_values(kernel, jnp.asarray(V, jnp.float32)), dense @ V,
                               rtol=2e-6, atol=2e-6)
    pi = rng.random((S, A))
    pi /= pi.sum(-1, keepdims=True)
    np.testing.assert_allclose(em.policy_matrix(kernel, jnp.asarray(pi, jnp.float32)),
                               np.einsum("sa,sat->st", pi, dense), rtol=1e-6, atol=1e-7)


def _optimal_q_by_enumeration(P, R, gamma):
    """``Q*`` of a small dense model: the best of every deterministic policy's exact values (float64)."""
    S, A = R.shape
    best = np.full(S, -np.inf)
    for actions in itertools.product(range(A), repeat=S):
        idx = np.arange(S), np.asarray(actions)
        V = np.linalg.solve(np.eye(S) - gamma * P[idx], R[idx])
        best = np.maximum(best, V)
    return R + gamma * P @ best


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_discounted_greedy_policy_is_optimal(seed):
    rng = np.random.default_rng(seed)
    S, A, K, gamma = 6, 3, 2, 0.95
    kernel, dense = _random_kernel(rng, S, A, K, n_real=S)
    R = rng.random((S, A))
    Q = _optimal_q_by_enumeration(dense, R, gamma)
    top = np.sort(Q, -1)
    assert np.min(top[:, -1] - top[:, -2]) > 1e-4  # no near-ties: the optimal actions are well defined
    pi = em.discounted_greedy_policy(kernel, jnp.asarray(R, jnp.float32), gamma, jnp.ones(A, bool))
    np.testing.assert_array_equal(pi, np.eye(A)[np.argmax(Q, -1)])


def test_padded_actions_mirror_action_zero():
    rng = np.random.default_rng(5)
    S, A, K = 5, 3, 2
    kernel, _ = _random_kernel(rng, S, A, K, n_real=S)
    R = jnp.asarray(rng.random((S, A)), jnp.float32)
    mask = jnp.asarray([True, True, False])
    pi = em.discounted_greedy_policy(kernel, R.at[:, 2].set(100.0), 0.9, mask)  # the padded action's reward ignored
    assert np.all(np.asarray(pi)[:, 2] == 0) and np.all(np.asarray(pi).sum(-1) == 1)
    two = kernel.replace(states=kernel.states[:, :2], probs=kernel.probs[:, :2], uniform=kernel.uniform[:, :2])
    np.testing.assert_array_equal(pi[:, :2], em.discounted_greedy_policy(two, R[:, :2], 0.9, jnp.ones(2, bool)))


def _dense_q(state: ucrl2.UCRL2State) -> jax.Array:
    """The discounted optimal ``Q`` of UCRL2's estimated model, as the dense route computes it before its greedy step
    (:func:`agents.ucrl2._dense_policy`)."""
    P, R = ucrl2.estimated_model(state)
    mask = state.action_mask
    return dp.solve_discounted(copy_action_zero(P, mask), state.hparams.policy_discount,
                               rewards=copy_action_zero(R, mask)).Q


@pytest.mark.parametrize("family, params", [
    ("RiverSwim", dict(size=8, p_lazy=0.1, make_reward_stochastic=True)),
    pytest.param("MiniGridEmpty", dict(size=5, p_lazy=0.3, n_starting_states=2, make_reward_stochastic=True),
                 marks=pytest.mark.nightly),
])
def test_ucrl2_policy_estimate_equals_the_dense_route(family, params):
    """After a lockstep run, UCRL2's slots hold every transition and its policy estimate is the dense route's
    (:func:`agents.tabular_common.discounted_greedy_policy` of :func:`agents.ucrl2.estimated_model`), at every one
    of several checkpoints (early: many unvisited pairs; later: most pairs visited).

    The two routes sum in different orders, so where two actions' values tie to the last bits the greedy choice may
    differ with the CPU's vector width (seen on one machine of two: MiniGrid-Empty after 30 steps, one state of 300
    with values 93.96376 / 93.96376 / 93.96377). There the test asks only that both choices be greedy for the dense
    values up to 4 units in the last place, at no more than one state per member."""
    mdp = jaxmdp.make(family, episodic=False, seed=0, **params)
    assert spec_of(mdp, 10).max_successors == mdp.max_successors
    dense_route = jax.jit(jax.vmap(ucrl2._dense_policy))
    sparse_route = jax.jit(jax.vmap(ucrl2.policy))
    dense_q = jax.jit(jax.vmap(_dense_q))
    for n_steps in (30, 400, 3000):
        grid = runner.product([mdp], [ucrl2.UCRL2.default_hparams], [0, 1, 2])
        states = runner.run(ucrl2.UCRL2, grid, n_steps, log_period=n_steps).agent_state
        # Per pair as many as the epoch schedule's independent visit counter.
        np.testing.assert_array_equal(states.counts.sum(-1), states.schedule.visits)
        sparse, dense = np.asarray(sparse_route(states)), np.asarray(dense_route(states))
        apart = np.argwhere((sparse != dense).any(-1))
        assert np.all(np.bincount(apart[:, 0], minlength=3) <= 1), apart
        Q = np.asarray(dense_q(states))
        for b, s in apart:
            chosen = Q[b, s, [sparse[b, s].argmax(), dense[b, s].argmax()]]
            np.testing.assert_allclose(chosen, Q[b, s].max(), rtol=4 * np.finfo(np.float32).eps)


def _dense_boxes(states, filled, lo, hi, room_other, state_mask):
    """Slot boxes written densely: ``[0, room_other]`` at real states outside the filled slots, the filled slots'
    bounds at theirs (an empty slot holds state 0 and the box ``[0, room_other]``)."""
    S, A, K = states.shape
    dense_lo = np.zeros((S, A, S), np.float32)
    dense_hi = np.where(state_mask, np.asarray(room_other)[..., None], 0.0).astype(np.float32) * np.ones(S, np.float32)
    for i, j, k in itertools.product(range(S), range(A), range(K)):
        if filled[i, j, k]:
            dense_lo[i, j, states[i, j, k]], dense_hi[i, j, states[i, j, k]] = lo[i, j, k], hi[i, j, k]
        else:
            assert lo[i, j, k] == 0.0 and hi[i, j, k] == room_other[i, j]
    return dense_lo, dense_hi


@pytest.mark.nightly  # by default: test_ucrl2_policy_estimate_equals_the_dense_route
def test_ucrl2_plans_on_the_same_boxes_as_the_dense_counts():
    """UCRL2's slot boxes are :func:`confidence_box` of its dense widths, entry for entry, and its plan matches the
    dense planner's (same sweeps, optimistic ``Q`` within rounding)."""
    mdp = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=5, p_lazy=0.3, n_starting_states=2,
                      make_reward_stochastic=True)
    # alpha_p small: the tuned 0.99 keeps every box the whole simplex (c >= 1) until a pair has ~290 visits, where
    # the plan would not depend on the counts at all.
    hp = ucrl2.UCRL2.default_hparams.replace(alpha_p=0.001)
    # Three seeds, as in the test above: the same runner program (hyperparameters are data), compiled once per module.
    states = runner.run(ucrl2.UCRL2, runner.product([mdp], [hp], [0, 1, 2]), 2000, log_period=2000).agent_state
    dense_plan = jax.jit(jax.vmap(ucrl2._dense_plan))
    for m in range(2):
        state = jax.tree.map(lambda x: jnp.asarray(x[m]), states).replace(plan_due=jnp.ones((), bool))
        st, lo, hi, room, r_tilde = map(np.asarray, ucrl2.sparse_confidence(state))
        p_hat, width, r_dense = ucrl2.confidence_widths(state)
        want_lo, want_hi = confidence_box(p_hat, width, state.state_mask)
        got_lo, got_hi = _dense_boxes(st, np.asarray(state.successors.counts) > 0, lo, hi, room,
                                      np.asarray(state.state_mask))
        np.testing.assert_array_equal(got_lo, want_lo)
        np.testing.assert_array_equal(got_hi, want_hi)
        np.testing.assert_array_equal(r_tilde, r_dense)
        assert np.mean(room < 0.5) > 0.3 and np.mean(lo > 0) > 0.1  # informative boxes
        new = jax.jit(ucrl2.plan)(jax.random.key(0), state)
        old = jax.tree.map(lambda x: x[0], dense_plan(jax.tree.map(lambda x: x[None], state)))
        assert int(new.evi_iterations) == int(old.iterations) and bool(new.evi_converged)
        np.testing.assert_allclose(new.Q, old.Q, rtol=1e-5, atol=1e-5)


def _near_tie(state: psrl_continuous.PSRLContinuousState) -> jax.Array:
    """States whose best action under the dense posterior mean leads the next by ``(0, 1e-4 (1 + max|Q|)]``."""
    P = dirichlet_mean(psrl_continuous._posterior_alpha(state))
    R = normal_gamma_mean(state.rewards)
    Q = dp.solve_discounted(P, state.hparams.policy_discount, rewards=R).Q
    top = jnp.sort(Q, axis=-1)
    gap = top[:, -1] - top[:, -2]
    return (gap > 0) & (gap <= 1e-4 * (1.0 + jnp.max(jnp.abs(Q))))


@pytest.mark.parametrize("family, params", [
    ("RiverSwim", dict(size=8, p_lazy=0.1, make_reward_stochastic=True)),
    pytest.param("MiniGridEmpty", dict(size=5, p_lazy=0.3, n_starting_states=2, make_reward_stochastic=True),
                 marks=pytest.mark.nightly),
])
@pytest.mark.nightly  # by default: test_psrl_continuous.py's p^- slots against the dense rows
def test_psrl_continuous_policy_estimate_equals_the_dense_posterior_mean(family, params):
    """PSRL continuous's policy estimate on its slots (the posterior mean as counts plus a uniform prior part) is the
    dense posterior mean's after lockstep runs wherever no near-tie lets rounding decide (the two kernels differ in
    the last bits: the dense mean divides by the float sum of the concentrations, 1e-6 off on MiniGridEmpty); its
    kernel is the float64 posterior mean to 1e-6; broken, flagged slots are reported by the agent's diagnostics."""
    mdp = jaxmdp.make(family, episodic=False, seed=0, **params)
    agent = psrl_continuous.PSRL_CONTINUOUS
    hp = agent.default_hparams.replace(max_psi=psrl_continuous.psi(agent.default_hparams, mdp.n_states,
                                                                  mdp.n_actions))
    dense_route = jax.jit(jax.vmap(psrl_continuous._dense_policy))
    sparse_route = jax.jit(jax.vmap(psrl_continuous.policy))
    for n_steps in (30, 1500):
        states = runner.run(agent, runner.product([mdp], [hp], [0, 1, 2]), n_steps, log_period=n_steps).agent_state
        # The slots hold every transition: per pair as many as the epoch schedule's independent visit counter.
        np.testing.assert_array_equal(states.counts.sum(-1), states.schedule.visits)
        # Equal wherever the dense optimal Q is exactly tied (both routes take the lowest index) or separates the best
        # action from the next by more than rounding; near-ties are rare.
        near = np.asarray(jax.vmap(_near_tie)(states))
        got, want = np.asarray(sparse_route(states)), np.asarray(dense_route(states))
        np.testing.assert_array_equal(got[~near], want[~near])
        assert np.mean(near) < 0.05
        one = jax.tree.map(lambda x: jnp.asarray(x[0]), states)
        kernel = psrl_continuous.posterior_mean_kernel(one)
        S = mdp.n_states
        rows = np.broadcast_to(np.arange(S)[:, None], kernel.states.shape[:2])
        dense_kernel = np.zeros((S, mdp.n_actions, S), np.float64)
        for k in range(kernel.states.shape[-1]):
            np.add.at(dense_kernel, (rows, np.arange(mdp.n_actions)[None, :], np.asarray(kernel.states[..., k])),
                      np.asarray(kernel.probs[..., k], np.float64))
        dense_kernel += np.asarray(kernel.uniform, np.float64)[..., None] / S
        counts = np.asarray(one.counts, np.float64)  # the posterior mean in float64: (1/S + N(s, a, s')) / (1 + N(s, a))
        np.testing.assert_allclose(dense_kernel, (1.0 / S + counts) / (1.0 + counts.sum(-1, keepdims=True)), rtol=1e-6)
        # Slots that missed counts (a spec below the MDP's successors) are reported, not papered over.
        assert int(agent.diagnostics(one)["slots_overflowed"]) == 0
        lost = one.successors.replace(counts=one.successors.counts.at[..., 1:].set(0), overflowed=jnp.ones((), bool))
        assert int(agent.diagnostics(one.replace(successors=lost))["slots_overflowed"]) == 1


def _banded_kernel(rng, S, A, K, n_real, w):
    """A kernel whose slots join states at most ``w`` apart in a random order of the real states (padding states
    last), with a uniform part; unvisited pairs (no slot, uniform 1) included. Returns it with its band order and the
    dense numpy kernel."""
    order = np.concatenate([rng.permutation(n_real), np.arange(n_real, S)])
    pos = np.argsort(order)
    states = np.zeros((S, A, K), np.int64)
    for s, a in itertools.product(range(n_real), range(A)):
        near = [order[p] for p in range(max(pos[s] - w, 0), min(pos[s] + w + 1, n_real))]
        states[s, a] = rng.choice(near, size=K, replace=len(near) < K)
    probs = rng.random((S, A, K)) * (rng.random((S, A, K)) < 0.8)
    probs[n_real:] = 0.0
    uniform = rng.random((S, A)) * (rng.random((S, A)) < 0.5)
    unvisited = rng.random((S, A)) < 0.1
    probs[unvisited], uniform[unvisited] = 0.0, 1.0
    total = probs.sum(-1) + uniform
    uniform[total == 0], total[total == 0] = 1.0, 1.0
    probs, uniform = probs / total[..., None], uniform / total
    dense = np.zeros((S, A, S))
    for s, a, k in itertools.product(range(S), range(A), range(K)):
        dense[s, a, states[s, a, k]] += probs[s, a, k]
    dense[..., :n_real] += uniform[..., None] / n_real
    kernel = em.SparseKernel(jnp.asarray(states, jnp.int32), jnp.asarray(probs, jnp.float32),
                             jnp.asarray(uniform, jnp.float32), jnp.asarray(np.arange(S) < n_real),
                             order=jnp.asarray(order, jnp.int32), bandwidth=w)
    return kernel, dense


@pytest.mark.parametrize("S,n_real,w,gamma", [(30, 30, 3, 0.99), (41, 37, 6, 0.9), (12, 12, 11, 0.999)])
def test_banded_policy_values_solve_the_float64_system(S, n_real, w, gamma):
    # The banded elimination with the Sherman-Morrison correction for the uniform part, against a float64 dense solve
    # and against the dense route without the order, for a stochastic and a deterministic policy.
    rng = np.random.default_rng(S + w)
    A, K = 3, 3
    kernel, dense = _banded_kernel(rng, S, A, K, n_real, w)
    assert bool(kernel.in_band())
    R = rng.random((S, A))
    g32 = float(np.float32(gamma))  # the discount the float32 computation sees
    for pi in (rng.dirichlet(np.ones(A), size=S), np.eye(A)[rng.integers(0, A, S)]):
        want = np.linalg.solve(np.eye(S) - g32 * np.einsum("sa,sat->st", pi, dense), (pi * R).sum(-1))
        args = (jnp.asarray(pi, jnp.float32), jnp.asarray(R, jnp.float32), gamma)
        got = np.asarray(jax.jit(em.policy_values)(kernel, *args))
        np.testing.assert_allclose(got, want, rtol=0, atol=3e-6 * np.max(np.abs(want)))
        # The dense float32 solve is the less accurate of the two (3e-6 here at gamma = 0.99).
        plain = np.asarray(jax.jit(em.policy_values)(kernel.replace(order=None, bandwidth=None), *args))
        np.testing.assert_allclose(plain, want, rtol=0, atol=2e-5 * np.max(np.abs(want)))


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_discounted_greedy_policy_on_a_band_order_is_optimal(seed):
    rng = np.random.default_rng(seed)
    S, A, K, gamma = 7, 3, 2, 0.95
    kernel, dense = _banded_kernel(rng, S, A, K, n_real=S - 1, w=2)
    R = rng.random((S, A))
    Q = _optimal_q_by_enumeration(dense, R, gamma)
    top = np.sort(Q, -1)
    assert np.min(top[:, -1] - top[:, -2]) > 1e-4
    pi = em.discounted_greedy_policy(kernel, jnp.asarray(R, jnp.float32), gamma, jnp.ones(A, bool))
    np.testing.assert_array_equal(pi, np.eye(A)[np.argmax(Q, -1)])


@pytest.mark.nightly  # by default: test_gth_banded.py's wrong-band-order fallback
def test_a_kernel_outside_its_band_order_is_solved_densely():
    # A hint too narrow for the kernel: the check sees it and the policy is the dense route's, member by member
    # under vmap; trusting the hint would have dropped transitions and chosen differently.
    rng = np.random.default_rng(11)
    S, A, K, gamma = 40, 3, 3, 0.95
    kernel, _ = _banded_kernel(rng, S, A, K, n_real=S, w=8)
    narrow = kernel.replace(order=jnp.asarray(rng.permutation(S), jnp.int32))  # another order: the band no longer holds
    assert bool(kernel.in_band()) and not bool(narrow.in_band())
    R = jnp.asarray(rng.random((S, A)), jnp.float32)
    mask = jnp.ones(A, bool)
    plain = em.discounted_greedy_policy(kernel.replace(order=None, bandwidth=None), R, gamma, mask)
    both = jax.tree.map(lambda a, b: jnp.stack([a, b]), kernel, narrow)
    got = jax.jit(jax.vmap(lambda k: em.discounted_greedy_policy(k, R, gamma, mask)))(both)
    np.testing.assert_array_equal(got[1], plain)
    np.testing.assert_array_equal(got[0], plain)  # no near-tie here: the banded route agrees
    trusted = jax.jit(lambda k: em._greedy_policy(k, R, gamma, mask)[0])(narrow)
    assert not np.array_equal(trusted, plain)


def test_runner_hands_the_band_order_to_ucrl2_and_psrl_continuous():
    # On MDPs with a band order (64 states or more, on a CPU) the agents' slot tables carry their member's order (the
    # banded evaluations themselves are tested above).
    mdps = [jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=6, p_lazy=0.2),
            jaxmdp.make("SimpleGrid", episodic=False, seed=0, size=9, p_rand=0.1)]
    for agent, hp in ((ucrl2.UCRL2, ucrl2.UCRL2.default_hparams),
                      (psrl_continuous.PSRL_CONTINUOUS, psrl_continuous.PSRL_CONTINUOUS.default_hparams)):
        grid = runner.product(mdps, [hp], [0])
        orders, width = runner._band(grid.mdps, grid.mdp_index)
        assert orders is not None
        init = runner._init_program(agent, False, width)
        carry = init(grid.mdps, jax.device_put(grid.mdp_index), grid.hparams, grid.key_data, jnp.int32(100), orders)
        table = carry.agent_state.successors
        np.testing.assert_array_equal(table.order, orders)
        assert table.bandwidth == width


# ---------------------------------------------------------------------------------------------------------------
# Warm-started policy estimates
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("banded", [False, True])
def test_a_warm_start_gives_the_cold_estimate_and_the_exact_values_of_its_policy(banded, monkeypatch):
    # From any start (zeros, the estimate's own values, those values perturbed, a far constant) the estimate is the
    # cold one on a kernel without near-ties (the enumerated optimum, action gaps checked), and the returned values are
    # that policy's exact values (float64 solve). From its own values the value iteration stops after one sweep.
    rng = np.random.default_rng(21)
    S, A, K, gamma = 9, 3, 2, 0.95
    kernel, dense = _banded_kernel(rng, S, A, K, n_real=S, w=2)
    kernel = kernel if banded else kernel.replace(order=None, bandwidth=None)
    R = rng.random((S, A))
    Q = _optimal_q_by_enumeration(dense, R, gamma)
    top = np.sort(Q, -1)
    assert np.min(top[:, -1] - top[:, -2]) > 1e-3
    best = np.eye(A)[np.argmax(Q, -1)]
    g32 = float(np.float32(gamma))
    exact = np.linalg.solve(np.eye(S) - g32 * np.einsum("sa,sat->st", best, dense), (best * R).sum(-1))
    R32, mask = jnp.asarray(R, jnp.float32), jnp.ones(A, bool)
    phases_of = em.greedy_policy_phases
    handed = []  # what warm_greedy_policy hands the phases when traced (the band's two routes: two calls)

    def spy(kernel, R, discount, action_mask, u0=None):
        handed.append(None if u0 is None else u0.shape)
        return phases_of(kernel, R, discount, action_mask, u0)

    monkeypatch.setattr(em, "greedy_policy_phases", spy)
    warm = jax.jit(lambda u: em.warm_greedy_policy(kernel, R32, gamma, mask, u))
    cold_pi, V = jax.jit(lambda: em.warm_greedy_policy(kernel, R32, gamma, mask, None))()
    np.testing.assert_array_equal(cold_pi, best)
    np.testing.assert_array_equal(em.discounted_greedy_policy(kernel, R32, gamma, mask), best)
    np.testing.assert_allclose(V, exact, rtol=2e-6)
    handed.clear()
    for u in (np.zeros(S), np.asarray(V), np.asarray(V) + rng.normal(0, 1, S), np.full(S, 50.0)):
        pi, V2 = warm(jnp.asarray(u, jnp.float32))
        np.testing.assert_array_equal(pi, best)
        np.testing.assert_allclose(V2, exact, rtol=2e-6)
    assert handed == [(S,)] * (2 if banded else 1)  # traced once, the start handed on
    phases = jax.jit(lambda u: phases_of(kernel, R32, gamma, mask, u))
    assert int(phases(V)[1].iterations) == 1
    assert int(phases(None)[1].iterations) > 50  # from zeros: log(1e-3) / log(0.95) sweeps at least, about 135


@pytest.mark.nightly  # by default: test_runner.py's warm-start test
@pytest.mark.parametrize("agent", [ucrl2.UCRL2, psrl_continuous.PSRL_CONTINUOUS], ids=lambda a: a.name)
def test_agents_warm_policy_from_the_previous_log_is_their_policy(agent, monkeypatch):
    # Along a random-play stream, each log's estimate started from the previous log's values is the agent's cold
    # policy (no near-ties on this MDP); a cold call hands on its values, the first start is zeros. The policies alone
    # cannot show that the start is used (policy iteration ends at the same policy from any start), so a spy records
    # what the agent hands the estimate when it is traced: the start, not None.
    mdp = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=5, p_lazy=0.3, n_starting_states=2,
                      make_reward_stochastic=True)
    hp = agent.default_hparams
    play = jax.jit(lambda k, st: played(agent, mdp, hp, 50, k, st))
    handed = []
    solve = em.warm_greedy_policy

    def spy(kernel, R, discount, action_mask, u0):
        handed.append(None if u0 is None else u0.shape)
        return solve(kernel, R, discount, action_mask, u0)

    monkeypatch.setattr(em, "warm_greedy_policy", spy)
    warm, cold = jax.jit(agent.hints.warm_policy), jax.jit(agent.policy)
    state = agent.init(jax.random.key(0), spec_of(mdp, 10_000), hp)
    start = agent.hints.policy_start(state)
    np.testing.assert_array_equal(start, np.zeros(mdp.n_states))
    for i in range(6):
        state = play(jax.random.key(i), state)
        pi, start = warm(state, start)
        np.testing.assert_array_equal(pi, cold(state))
    np.testing.assert_array_equal(jax.jit(lambda st: agent.hints.warm_policy(st, None)[1])(state), start)
    assert handed == [(mdp.n_states,), None, None]  # traced once each: warm, cold policy, cold warm_policy
