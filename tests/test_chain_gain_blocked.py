"""Blocked GTH elimination (``dp._gth_eliminate``) and ``dp.chain_gain`` against float64 numpy references
(``numpy_reference.gth_elimination`` and ``.chain_gain``) on random chains that exercise several blocks."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

import numpy_reference as ref
from jaxmdp import dynamic_programming as dp
from jaxmdp import gth


def _normalise(P):
    P = np.where(P.sum(1, keepdims=True) > 0, P, np.eye(len(P)))
    return P / P.sum(1, keepdims=True)


def dense_chain(rng, S):
    return _normalise(rng.random((S, S)))


def grid_chain(rng, S):
    """A lazy random walk on a grid of ``S`` cells (``ceil(sqrt S)`` wide), random move probabilities."""
    w = int(np.ceil(np.sqrt(S)))
    P = np.zeros((S, S))
    for s in range(S):
        x, y = divmod(s, w)
        for dx, dy in ((0, 1), (1, 0), (0, -1), (-1, 0)):
            t = (x + dx) * w + (y + dy)
            ok = 0 <= x + dx and 0 <= y + dy < w and t < S
            P[s, t if ok else s] += rng.random()
        P[s, s] += 0.1
    return _normalise(P)


def slow_chain(rng, S):
    """Nearly decomposable: clusters of 8 states with dense moves inside, and probabilities 1e-6..1e-3 (each link
    present with probability 1/2, plus one 1e-6 link a cluster) to the next cluster of a ring, so the chain mixes
    slowly (``1 - |lambda_2|`` is ~1e-4 at S = 37 and ~1e-5 at S = 130)."""
    cluster = np.arange(S) // 8
    n = cluster.max() + 1
    P = np.where(cluster[:, None] == cluster[None, :], rng.random((S, S)), 0.0)
    ring = cluster[None, :] == (cluster[:, None] + 1) % n
    P += np.where(ring & (rng.random((S, S)) < 0.5), 10 ** rng.uniform(-6, -3, (S, S)), 0.0)
    if n > 1:
        first = np.flatnonzero(np.r_[True, cluster[1:] != cluster[:-1]])
        P[first, np.roll(first, -1)] += 1e-6
    return _normalise(P)


def multichain(rng, S):
    """Closed classes (dense, periodic cycles, absorbing padding states) and transient states leaking into them,
    some slowly (1e-4); states shuffled."""
    P = np.zeros((S, S))
    n_pad = max(1, S // 10)
    sizes, used = [], n_pad
    while used < S * 2 // 3:
        sizes.append(int(rng.integers(1, max(2, S // 5) + 1)))
        used += sizes[-1]
    start = n_pad
    classes = []
    for q, size in enumerate(sizes):
        idx = np.arange(start, min(start + size, S))
        start += size
        if not len(idx):
            break
        if q % 3 == 1:  # periodic: a deterministic cycle
            P[idx, np.roll(idx, -1)] = 1.0
        elif q % 3 == 2 and len(idx) > 1:  # periodic of period 2: bipartite
            half = len(idx) // 2
            P[np.ix_(idx[:half], idx[half:])] = rng.random((half, len(idx) - half))
            P[np.ix_(idx[half:], idx[:half])] = rng.random((len(idx) - half, half))
        else:
            P[np.ix_(idx, idx)] = rng.random((len(idx), len(idx))) * (rng.random((len(idx), len(idx))) < 0.6)
            P[idx, np.roll(idx, -1)] += 0.1
        classes.append(idx)
    P[np.arange(n_pad), np.arange(n_pad)] = 1.0  # padding: isolated absorbing states
    for s in range(start, S):
        targets = rng.choice(S, size=min(S, 4), replace=False)
        P[s, targets] = rng.random(len(targets)) * np.where(targets >= s, 1.0, 1e-4 ** rng.random(len(targets)))
        P[s, s] = 0.0
        if P[s].sum() == 0:
            P[s, classes[0][0]] = 1.0
    perm = rng.permutation(S)
    return _normalise(P)[np.ix_(perm, perm)]


KINDS = {"dense": dense_chain, "grid": grid_chain, "slow": slow_chain, "multichain": multichain}
CASES = [(kind, S, seed) for kind in KINDS for S in (5, 37, 130) for seed in range(2)]


def chain(kind, S, seed):
    rng = np.random.default_rng(1000 * seed + S)
    P = KINDS[kind](rng, S)
    r = rng.random(S)
    return P, r


# What the scalar elimination (block 1, and main before blocking) meets on these chains: relative errors up to 7e-7,
# from rounding the float64 chain and rewards to float32 and from S-term sums (the blocked one: up to 7.6e-7).
TOL = 1e-6

chain_gain = jax.jit(dp.chain_gain, static_argnames="block")
eliminate = jax.jit(gth.gth_eliminate, static_argnames=("block", "stages"))


def test_reference_gain_matches_the_null_space():
    # The float64 reference itself: a dense chain's stationary distribution from the null space of (I - P)^T.
    P, r = chain("dense", 37, 0)
    mu = scipy.linalg.null_space((np.eye(37) - P).T)[:, 0]
    np.testing.assert_allclose(ref.chain_gain(P, r), mu @ r / mu.sum(), rtol=1e-12)


@pytest.mark.parametrize("kind,S,seed", CASES)
def test_chain_gain_matches_float64_reference(kind, S, seed):
    P, r = chain(kind, S, seed)
    expected = ref.chain_gain(P, r)
    Pj, rj = jnp.asarray(P, jnp.float32), jnp.asarray(r, jnp.float32)
    for block in (1, 4, 32, 64):
        np.testing.assert_allclose(chain_gain(Pj, rj, block=block), expected, rtol=TOL, err_msg=f"block {block}")


#: (block, stages) of the blocked elimination checked here and on the drifting chain: blocks that pad (32 and 64 at
#: S = 37) or not, one or several stages.
BLOCKS_STAGES = ((1, 1), (4, 8), (16, 2), (32, 1), (32, 4), (64, 4))


@pytest.mark.parametrize("kind,S", [(kind, S) for kind in KINDS for S in (37, 130)])
def test_blocked_elimination_matches_float64_scalar_elimination(kind, S):
    # Every stored entry (normalised columns, rows at elimination, the sums s_k) to a relative 1e-6, and exactly the
    # same zeros (they decide the classes' roots), for block sizes that pad (32, 16 at S = 37) or not, in one or several
    # stages of shrinking windows.
    P, _ = chain(kind, S, 0)
    M, s = ref.gth_elimination(P)
    for block, stages in BLOCKS_STAGES:
        Mj, sj = (np.asarray(x, np.float64) for x in eliminate(jnp.asarray(P, jnp.float32), block=block, stages=stages))
        np.testing.assert_array_equal(Mj == 0, M == 0)
        np.testing.assert_array_equal(sj == 0, s == 0)
        np.testing.assert_allclose(Mj, M, rtol=TOL, atol=0, err_msg=f"block {block}, stages {stages}")
        np.testing.assert_allclose(sj, s, rtol=TOL, atol=0, err_msg=f"block {block}, stages {stages}")


def test_chain_gain_rejects_a_block_below_one():
    with pytest.raises(ValueError, match="block"):
        dp.chain_gain(jnp.eye(3), jnp.zeros(3), block=0)


@pytest.mark.parametrize("S", [37, 130])
def test_cases_have_the_structure_they_claim(S):
    # So that the gain tests do cover them: multichain cases have several closed classes, a periodic one (a state
    # with no self-loop whose return times share a factor > 1: P^t[s, s] = 0 for every odd t up to S), transient
    # states and absorbing padding; slow cases mix slowly (spectral gap below 1e-3).
    for seed in range(2):
        P, _ = chain("multichain", S, seed)
        reach = ref.reachability(P)
        recurrent = np.all(~reach | reach.T, axis=1)
        n_classes = len({tuple(np.flatnonzero(reach[s] & reach[:, s])) for s in np.flatnonzero(recurrent)})
        assert n_classes >= 3 and (~recurrent).sum() >= 3
        assert np.any((np.diag(P) == 1.0) & (P.sum(0) == 1.0))  # an isolated absorbing state
        powers, Pt = [], np.eye(S)
        for _ in range(S):
            Pt = Pt @ P
            powers.append(np.diag(Pt))
        odd_returns = np.array(powers)[0::2]  # P^1, P^3, ...
        assert np.any(recurrent & (np.diag(P) == 0) & np.all(odd_returns == 0, axis=0))
        P, _ = chain("slow", S, seed)
        assert 1 - np.sort(np.abs(np.linalg.eigvals(P)))[-2] < 1e-3


def test_chain_gain_under_vmap_matches_the_reference():
    # The runner vmaps the dense solve over members off CPU: batched blocks, windows and products.
    chains = [chain(kind, 37, 0) for kind in KINDS]
    P = jnp.asarray(np.stack([c[0] for c in chains]), jnp.float32)
    r = jnp.asarray(np.stack([c[1] for c in chains]), jnp.float32)
    g = jax.jit(jax.vmap(lambda P, r: dp.chain_gain(P, r, block=8)))(P, r)
    for q, (Pq, rq) in enumerate(chains):
        np.testing.assert_allclose(g[q], ref.chain_gain(Pq, rq), rtol=TOL)


def drifting_chain(S: int, up: float = 0.6, down: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """A birth-death chain that drifts towards higher positions (RiverSwim's optimal chain has this shape): the mass
    leaving a state downwards is ``down``, so products of ``b`` factors ``1 / s_k`` within a block exceed float32."""
    P = np.zeros((S, S))
    for s in range(S):
        P[s, min(s + 1, S - 1)] += up
        P[s, max(s - 1, 0)] += down
        P[s, s] += 1.0 - up - down
    r = np.zeros(S)
    r[-1] = 1.0
    return P, r


@pytest.mark.parametrize("S", [37, 130])
def test_a_chain_drifting_upwards_stays_finite_and_exact(S):
    # Regression: the first blocked version carried b x b coefficient matrices, products of 1 / s_k factors; on this
    # chain (and the benchmark's RiverSwim/prms_3 optimal policy, 80 states) they overflowed to inf, and the gain came
    # out 0 or NaN for block 32. The panels now hold the scalar algorithm's bounded numbers. (Factors near 1 / 0.02
    # exceed float32 after about 23 of them; the sizes, blocks and stages are those of the tests above, so their
    # compiled programs are reused.)
    P, r = drifting_chain(S)
    expected = ref.chain_gain(P, r)
    M, s = ref.gth_elimination(P)
    Pj, rj = jnp.asarray(P, jnp.float32), jnp.asarray(r, jnp.float32)
    for block in (1, 4, 32, 64):
        np.testing.assert_allclose(chain_gain(Pj, rj, block=block), expected, rtol=TOL, err_msg=f"block {block}")
    for block, stages in BLOCKS_STAGES:
        Mj, sj = (np.asarray(x, np.float64) for x in eliminate(Pj, block=block, stages=stages))
        assert np.all(np.isfinite(Mj)) and np.all(np.isfinite(sj))
        np.testing.assert_allclose(sj, s, rtol=TOL, atol=0, err_msg=f"block {block}, stages {stages}")
