"""The continuous indicators' exact gain as the runner computes it on a CPU (certified bounds on the successor lists,
else the banded GTH elimination on the MDP's band order, unchecked: no dense solve) against a float64 dense
reference, on random sparse MDPs whose policies have several closed classes, absorbing states and transient states."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmdp
import numpy_reference as ref
from jaxmdp import dynamic_programming as dp
from jaxmdp import gth
from jaxmdp.experiment import indicators

S, A = 30, 3


def _random_mdp(seed: int) -> jaxmdp.MDP:
    """A chain of ``S`` states whose actions move at most 3 positions (up to 3 successors each, random masses), with
    absorbing pairs (a self-loop of mass 1, at about one pair in six) and states whose every action stays put or moves
    one way, so that policies split the chain into several closed classes with transient states between them. The
    states are shuffled, so the band order must find the band."""
    g = np.random.default_rng(seed)
    T = np.zeros((S, A, S))
    for s in range(S):
        for a in range(A):
            if g.random() < 1 / 6:
                T[s, a, s] = 1.0
                continue
            targets = np.clip(s + g.choice(np.arange(-3, 4), size=g.integers(1, 4), replace=False), 0, S - 1)
            np.add.at(T[s, a], targets, g.dirichlet(np.ones(len(targets))))
    perm = g.permutation(S)
    T = T[np.ix_(perm, np.arange(A), perm)]
    R = g.uniform(0.0, 1.0, (S, A))
    return jaxmdp.custom_mdp(T, R=R)


@functools.partial(jax.jit, static_argnames=("bandwidth", "sweeps"))
def _runner_gains(mdp, actions, order, bandwidth, sweeps):
    return jax.vmap(lambda p: indicators.policy_values(
        mdp, p, sweeps, order=order, bandwidth=bandwidth, check_band=False,
        give_up=indicators.ITERATIVE_GAIN_GIVE_UP if sweeps else None))(actions)


@jax.jit
def _certified(mdp, actions):
    def one(p):
        return dp.successor_gain_bounds(mdp, p, max_sweeps=indicators.ITERATIVE_GAIN_SWEEPS,
                                        give_up=indicators.ITERATIVE_GAIN_GIVE_UP).certified

    return jax.vmap(one)(actions)


@pytest.mark.parametrize("seed", [0] + [pytest.param(k, marks=pytest.mark.nightly) for k in range(1, 4)])
def test_runner_gains_are_the_dense_float64_gains_on_random_sparse_mdps(seed):
    # 24 deterministic policies per MDP (action indices, as the runner hands them over): the runner's route (bounds
    # first, banded elimination where they do not certify) and the banded elimination alone, each within the
    # indicators' tolerance of a float64 dense reference (classes by Warshall's closure, GTH per class, a linear solve
    # for the transient states): 2e-6 (1 + |g|), twice the bounds' certified relative width 1e-6 (the midpoint is
    # within half of it), which also covers the float32 elimination (1e-6 in test_gth_banded). The policies must
    # include multichain ones and ones with transient states, and some whose bounds do not certify (so the banded
    # branch of the runner's route runs); under lax.cond inside vmap both branches run, so the banded-only call
    # checks that branch on every policy.
    mdp = _random_mdp(seed)
    order, width = gth.band_order(mdp)
    assert width < S // 2
    g = np.random.default_rng(100 + seed)
    actions = g.integers(0, A, (24, S)).astype(np.int32)
    T, R = np.asarray(mdp.T, np.float64), np.asarray(mdp.R, np.float64)
    states = np.arange(S)
    expected, multichain, transient = [], 0, 0
    for pi in actions:
        # The float32 rows sum to 1 +- 6e-8; a transient block that drains slowly (I - P_TT conditioned at 1e5)
        # turns that into 1e-4 in the reference's linear solve, while GTH divides by the rows' off-diagonal sums.
        # The gain of the chain is that of its rows normalised in float64.
        P = T[states, pi] / T[states, pi].sum(-1, keepdims=True)
        expected.append(ref.chain_gain(P, R[states, pi]))
        reach = ref.reachability(P)
        recurrent = np.all(~reach | reach.T, axis=1)
        classes = {tuple(np.flatnonzero(reach[s] & reach[:, s])) for s in np.flatnonzero(recurrent)}
        multichain += len(classes) > 1
        transient += not recurrent.all()
    expected = np.stack(expected)
    assert multichain >= 12 and transient >= 12, (multichain, transient)
    certified = int(np.sum(_certified(mdp, jnp.asarray(actions))))
    assert 0 < certified < len(actions), certified
    order = jnp.asarray(order)
    for sweeps in (indicators.ITERATIVE_GAIN_SWEEPS, 0):
        got = np.asarray(_runner_gains(mdp, jnp.asarray(actions), order, width, sweeps), np.float64)
        bad = np.abs(got - expected) > 2e-6 * (1 + np.abs(expected))
        assert not bad.any(), (sweeps, np.argwhere(bad)[:5], got[bad][:5], expected[bad][:5])
