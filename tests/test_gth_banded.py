"""Banded GTH elimination (``jaxmdp.gth``), the band order of an MDP, and the banded exact gains of
``dp.chain_gain`` / ``dp.gain_vector`` against float64 references (scalar elimination in numpy, the dense route in
float64, reachability by Warshall's closure)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse
from scipy.sparse.csgraph import reverse_cuthill_mckee

import jaxmdp
import numpy_reference as ref
from jaxmdp import dynamic_programming as dp
from jaxmdp import gth
from conftest import nightly_beyond
from test_chain_gain_blocked import CASES, TOL, chain

banded = jax.jit(gth.gth_eliminate_banded, static_argnames=("bandwidth", "block"))
after = jax.jit(dp._gain_after_elimination, static_argnames=("block", "bandwidth"))


def band_chain(rng, S, w):
    """A random chain whose entries vanish outside ``|i - j| <= w``, some rows leaving mass to an absorbing set."""
    i, j = np.indices((S, S))
    P = np.where(np.abs(i - j) <= w, rng.random((S, S)) * (rng.random((S, S)) < 0.7), 0.0)
    out = np.where(rng.random(S) < 0.3, rng.random(S), 0.0)
    P[np.arange(S), np.minimum(np.arange(S) + 1, S - 1)] += 0.05  # keep every row non-empty
    total = P.sum(1) + out
    return P / total[:, None], out / total


@pytest.mark.parametrize("S,w,block", [(1, 0, 4), (7, 0, 4), (13, 2, 1), (40, 5, 16), (40, 5, 3), (61, 17, 16),
                                       (30, 29, 8)])
def test_banded_elimination_is_the_scalar_elimination_with_an_absorbing_state(S, w, block):
    # The absorbing set as one more state at position 0 of a scalar float64 elimination (numpy_reference).
    P, out = band_chain(np.random.default_rng(S + 100 * w), S, w)
    aug = np.zeros((S + 1, S + 1))
    aug[1:, 1:], aug[1:, 0] = P, out
    M_ref, s_ref = ref.gth_elimination(aug)
    M, scale = banded(jnp.asarray(P, jnp.float32), jnp.asarray(out, jnp.float32), bandwidth=w, block=block)
    np.testing.assert_allclose(scale, s_ref[1:], rtol=2e-6)
    band = np.abs(np.subtract.outer(np.arange(S), np.arange(S))) <= w
    np.testing.assert_allclose(np.where(band, M, 0.0), np.where(band, M_ref[1:, 1:], 0.0), rtol=2e-5, atol=1e-7)


def test_banded_elimination_without_absorbing_mass_matches_the_dense_one():
    P, _ = band_chain(np.random.default_rng(3), 90, 11)
    P /= P.sum(1, keepdims=True)
    M_b, s_b = banded(jnp.asarray(P, jnp.float32), jnp.zeros(90, jnp.float32), bandwidth=11, block=16)
    M_d, s_d = jax.jit(gth.gth_eliminate)(jnp.asarray(P, jnp.float32))
    np.testing.assert_allclose(s_b, s_d, rtol=2e-6)
    np.testing.assert_allclose(M_b, M_d, rtol=2e-5, atol=1e-7)


def test_banded_elimination_rejects_bad_sizes():
    with pytest.raises(ValueError, match="bandwidth"):
        gth.gth_eliminate_banded(jnp.eye(3), jnp.zeros(3), -1)
    with pytest.raises(ValueError, match="block"):
        gth.gth_eliminate_banded(jnp.eye(3), jnp.zeros(3), 1, block=0)


def _classes(P):
    reach = ref.reachability(P)
    rec = np.all(~reach | reach.T, axis=1)
    same = reach & reach.T & rec[:, None] & rec[None, :]
    return rec, np.argmax(same, axis=1)


ORDERS = ("rcm", "shuffled")


# The default profile: the first seed of every chain kind and size (both orders); the second seed nightly.
@pytest.mark.parametrize("kind,S,seed", nightly_beyond(CASES, lambda c: c[2] == 0))
@pytest.mark.parametrize("order_kind", ORDERS)
def test_banded_gain_matches_float64_reference(kind, S, seed, order_kind):
    # The banded path itself (not chain_gain, which may fall back): recurrent first in the given order, the band
    # measured on that matrix. One block size per case, so that a chain kind and size meets blocks of 1, 3, 16 and 1
    # over its four cases (every block and band width is a compile of its own: 4 per case took 112 of the suite's
    # seconds).
    P, r = chain(kind, S, seed)
    expected = ref.chain_gain(P, r)
    rec, label = _classes(P)
    if order_kind == "rcm":
        order = np.asarray(reverse_cuthill_mckee(scipy.sparse.csr_matrix((P + P.T) > 0), symmetric_mode=True))
    else:
        order = np.random.default_rng(seed).permutation(S)
    perm = order[np.argsort(~rec[order], kind="stable")]
    Pp, rp = P[np.ix_(perm, perm)], rec[perm]
    i, j = np.nonzero((Pp > 0) & ~(~rp[:, None] & rp[None, :]))
    w = int(np.max(np.abs(i - j), initial=0))
    # The widest band too: then every window reaches position 0 (and its end, the state itself, must stay out).
    band_block = (1, 3, 16)[(seed + 2 * ORDERS.index(order_kind)) % 3]
    for block, width in ((band_block, w), (16, S - 1)):
        g = after(jnp.asarray(Pp, jnp.float32), jnp.asarray(r[perm], jnp.float32), jnp.asarray(rp),
                  jnp.asarray(label[perm]), block=block, bandwidth=width)
        np.testing.assert_allclose(g, expected[perm], rtol=TOL, err_msg=f"block {block}, bandwidth {width}")


@pytest.mark.parametrize("kind,S,seed", nightly_beyond([c for c in CASES if c[1] > 5], lambda c: c[2] == 1))
def test_chain_gain_with_a_band_order_matches_float64_reference(kind, S, seed):
    # Any permutation with a bandwidth hint: the banded elimination where the hint holds (the widest band), the dense
    # one where not (a hint of 0 on these chains), the same gains either way.
    P, r = chain(kind, S, seed)
    expected = ref.chain_gain(P, r)
    order = jnp.asarray(np.random.default_rng(seed).permutation(S), jnp.int32)
    f = jax.jit(dp.chain_gain, static_argnames=("block", "bandwidth"))
    for w in (0, S - 1):
        g = f(jnp.asarray(P, jnp.float32), jnp.asarray(r, jnp.float32), order=order, bandwidth=w)
        np.testing.assert_allclose(g, expected, rtol=TOL, err_msg=f"bandwidth hint {w}")


def test_chain_gain_needs_order_and_bandwidth_together():
    with pytest.raises(ValueError, match="order and bandwidth"):
        dp.chain_gain(jnp.eye(2), jnp.ones(2), bandwidth=1)
    with pytest.raises(ValueError, match="order and bandwidth"):
        dp.gain_vector(jnp.eye(2)[:, None, :], jnp.ones((2, 1)), order=jnp.arange(2))


def _union_bandwidth(mdp, order):
    succ, p = np.asarray(mdp.succ), np.asarray(mdp.succ_p)
    pos = np.empty(len(order), int)
    pos[order] = np.arange(len(order))
    src = np.broadcast_to(np.arange(succ.shape[0])[:, None, None], succ.shape)
    return int(np.max(np.abs(pos[src] - pos[succ])[p > 0], initial=0))


@pytest.mark.parametrize("family,kw,natural,most", [
    ("MiniGridEmpty", dict(size=8, p_rand=0.1), 100, 40),
    ("SimpleGrid", dict(size=10, p_rand=0.1), 50, 12),
    ("RiverSwim", dict(size=20, p_rand=0.1), 1, 1),
])
def test_band_order_is_a_permutation_with_its_true_bandwidth(family, kw, natural, most):
    mdp = jaxmdp.make(family, episodic=False, seed=0, **kw)
    order, width = gth.band_order(mdp)
    assert sorted(order.tolist()) == list(range(mdp.n_states))
    assert width == _union_bandwidth(mdp, order)
    assert _union_bandwidth(mdp, np.arange(mdp.n_states)) >= natural  # the natural order's band is wide
    assert width <= most


def test_band_order_of_a_stack_is_per_member():
    mdps = [jaxmdp.make("SimpleGrid", episodic=False, seed=0, size=s, p_rand=0.1) for s in (5, 8)]
    stacked = jaxmdp.stack(mdps)
    orders, width = gth.band_order(stacked)
    assert orders.shape == (2, stacked.n_states)
    for k in range(2):
        assert sorted(orders[k].tolist()) == list(range(stacked.n_states))
    widths = [_union_bandwidth(jax.tree.map(lambda x: x[k], stacked), orders[k]) for k in range(2)]
    assert width == max(widths)
    assert widths[1] == gth.band_order(mdps[1]).bandwidth  # the largest member has no padding


def _gain64(mdp, pi):
    with jax.enable_x64(True):
        return np.asarray(dp.gain_vector(mdp.astype(jnp.float64), jnp.asarray(pi, jnp.float64)))


def _policies(mdp, rng):
    S, A = mdp.n_states, mdp.n_actions
    opt = np.asarray(dp.optimal_gain(mdp).policy)
    return {
        "deterministic": np.eye(A)[rng.integers(0, A, S)],
        "uniform": np.full((S, A), 1.0 / A),
        "optimal": np.eye(A)[opt] if opt.ndim == 1 else opt,
    }


@pytest.mark.parametrize("family,kw", [
    pytest.param("MiniGridEmpty", dict(size=8, p_rand=0.1), marks=pytest.mark.nightly),  # every policy irreducible
    ("MiniGridEmpty", dict(size=8, p_rand=0.0)),  # transient states and several classes
    ("DeepSea", dict(size=12, p_rand=0.0)),
    pytest.param("RiverSwim", dict(size=20, p_rand=0.0), marks=pytest.mark.nightly),
    pytest.param("Taxi", dict(size=4, length=1, width=1, space=1, n_locations=3, p_rand=0.0),
                 marks=pytest.mark.nightly),
])
def test_gain_vector_with_band_order_matches_float64(family, kw):
    # Unchecked, as the runner calls it: the MDP's own band order fits every policy's chain (NaN if one did not).
    mdp = jaxmdp.make(family, episodic=False, seed=0, **kw).strip()
    order, width = gth.band_order(mdp)
    f = jax.jit(dp.gain_vector, static_argnames=("bandwidth", "check_band"))
    for name, pi in _policies(mdp, np.random.default_rng(1)).items():
        g = f(mdp, jnp.asarray(pi, jnp.float32), order=jnp.asarray(order), bandwidth=width, check_band=False)
        np.testing.assert_allclose(g, _gain64(mdp, pi), rtol=TOL, atol=1e-7, err_msg=name)


@pytest.mark.nightly  # by default: test_runner_records_are_those_of_the_dense_elimination (unchecked)
def test_gain_vector_checked_and_unchecked_band_agree_bit_for_bit():
    # Transient states and several classes: the checked route takes its banded branch, the same numbers.
    mdp = jaxmdp.make("SimpleGrid", episodic=False, seed=0, size=7, p_rand=0.0).strip()
    order, width = gth.band_order(mdp)
    assert 2 * width < mdp.n_states
    rng = np.random.default_rng(3)
    for pi in (np.eye(mdp.n_actions)[rng.integers(0, mdp.n_actions, mdp.n_states)],
               np.full((mdp.n_states, mdp.n_actions), 1.0 / mdp.n_actions)):
        args = (mdp, jnp.asarray(pi, jnp.float32))
        checked = dp.gain_vector(*args, order=jnp.asarray(order), bandwidth=width)
        unchecked = dp.gain_vector(*args, order=jnp.asarray(order), bandwidth=width, check_band=False)
        assert np.all(np.isfinite(unchecked))
        np.testing.assert_array_equal(unchecked, checked)


@pytest.mark.nightly  # by default: test_gain_vector_with_band_order_matches_float64
def test_gain_vector_with_band_order_on_a_padded_stack_member():
    # Padding states are absorbing with reward 0: they form classes of their own and the real states' class stays
    # irreducible.
    small = jaxmdp.make("SimpleGrid", episodic=False, seed=0, size=5, p_rand=0.1)
    big = jaxmdp.make("SimpleGrid", episodic=False, seed=0, size=8, p_rand=0.1)
    stacked = jaxmdp.stack([small, big])
    member = jax.tree.map(lambda x: x[0], stacked.strip())
    orders, width = gth.band_order(stacked)
    rng = np.random.default_rng(2)
    for pi in (np.eye(member.n_actions)[rng.integers(0, member.n_actions, member.n_states)],
               np.full((member.n_states, member.n_actions), 1.0 / member.n_actions)):
        g = dp.gain_vector(member, jnp.asarray(pi, jnp.float32), order=jnp.asarray(orders[0]), bandwidth=width)
        np.testing.assert_allclose(g, _gain64(member, pi), rtol=TOL, atol=1e-7)
        want_small = _gain64(small.strip(), pi[:small.n_states, :small.n_actions] /
                             pi[:small.n_states, :small.n_actions].sum(1, keepdims=True))
        np.testing.assert_allclose(g[:small.n_states], want_small, rtol=TOL, atol=1e-7)


def test_gain_vector_with_a_wrong_band_order_falls_back_to_the_dense_elimination():
    mdp = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=8, p_rand=0.1).strip()
    pi = np.full((mdp.n_states, mdp.n_actions), 1.0 / mdp.n_actions)
    natural = jnp.arange(mdp.n_states, dtype=jnp.int32)  # its band is much wider than 3
    g = dp.gain_vector(mdp, jnp.asarray(pi, jnp.float32), order=natural, bandwidth=3)
    np.testing.assert_allclose(g, _gain64(mdp, pi), rtol=TOL, atol=1e-7)
    # Unchecked, the chain outside the band gives NaN, never a wrong number.
    g = dp.gain_vector(mdp, jnp.asarray(pi, jnp.float32), order=natural, bandwidth=3, check_band=False)
    assert np.all(np.isnan(g))


def _irreducible_numpy(succ, edge, real):
    S = succ.shape[0]
    adj = np.zeros((S, S), bool)
    src = np.broadcast_to(np.arange(S)[:, None], succ.shape)
    adj[src[edge], succ[edge]] = True
    reach = ref.reachability(adj.astype(float))
    x = int(np.argmax(real))
    leaves = np.any(adj[real][:, ~real])
    padding_moves = np.any(adj[~real] & ~np.eye(S, dtype=bool)[~real])
    return bool(not leaves and not padding_moves and np.all(reach[real, x]) and np.all(reach[x, real]))


def test_irreducible_matches_the_closure():
    rng = np.random.default_rng(5)
    f = jax.jit(dp._irreducible)
    seen = set()
    for trial in range(60):
        S, J = int(rng.integers(1, 9)), int(rng.integers(1, 4))
        succ = rng.integers(0, S, (S, J))
        edge = rng.random((S, J)) < (0.3 + 0.7 * rng.random())
        real = np.arange(S) < S - int(rng.integers(0, 3)) if S > 2 else np.ones(S, bool)
        if trial % 3 == 0:  # a ring over the real states: irreducible unless an edge leaves them
            n = int(real.sum())
            succ[:n, 0], edge[:n, 0] = (np.arange(n) + 1) % n, True
            if trial % 2 == 0:  # absorbing padding states
                succ[n:] = np.arange(n, S)[:, None]
        want = _irreducible_numpy(succ, edge, real)
        seen.add(want)
        assert bool(f(jnp.asarray(succ), jnp.asarray(edge), jnp.asarray(real))) == want, (succ, edge, real)
    assert seen == {True, False}


# ---------------------------------------------------------------------------------------------------------------
# The runner: band orders per member, the same records as the dense elimination
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.nightly  # by default: test_runner_records_are_those_of_the_dense_elimination
def test_runner_evaluates_changed_members_on_their_band_orders(monkeypatch):
    # Stacked MDPs of different sizes (padding), the certified bounds switched off so that every changed member takes
    # the exact elimination: banded gains equal float64 ones, unchanged members keep their cache.
    from jaxmdp.experiment import indicators, runner

    monkeypatch.setattr(indicators, "ITERATIVE_GAIN_SWEEPS", 0)
    mdps = [jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=8, p_rand=0.1),
            jaxmdp.make("SimpleGrid", episodic=False, seed=0, size=7, p_rand=0.0)]
    stacked = jaxmdp.stack(mdps).strip()
    index = np.asarray([0, 1, 1, 0])
    orders, width = runner._band(stacked, index)
    own = gth.band_order(stacked)
    np.testing.assert_array_equal(orders, own.order[index])
    assert width == own.bandwidth and 2 * width < stacked.n_states
    S, A = stacked.n_states, stacked.n_actions
    rng = np.random.default_rng(7)
    actions = jnp.asarray(rng.integers(0, 2, (4, S)), jnp.int32)  # every member has at least 2 actions
    cache = jnp.full((4, S), 7.0, jnp.float32)
    changed = jnp.asarray([True, True, False, True])
    f = jax.jit(lambda *a: runner._evaluate_changed(*a, orders=orders, bandwidth=width))
    out = np.asarray(f(stacked, jnp.asarray(index), actions, changed, cache))
    for b in (0, 1, 3):
        member = jax.tree.map(lambda x: x[index[b]], stacked)
        np.testing.assert_allclose(out[b], _gain64(member, np.eye(A)[np.asarray(actions[b])]), rtol=TOL, atol=1e-7)
    np.testing.assert_array_equal(out[2], cache[2])
    # The runner does not check its orders (no dense branch compiled): a wrong band would give NaN.
    narrow = jax.jit(lambda *a: runner._evaluate_changed(*a, orders=orders, bandwidth=1))
    assert np.all(np.isnan(np.asarray(narrow(stacked, jnp.asarray(index), actions, changed, cache))[[0, 1, 3]]))


@pytest.mark.nightly  # by default: test_indicators_banded.py's runner gains against the dense float64 gains
def test_runner_records_are_those_of_the_dense_elimination(monkeypatch):
    from jaxmdp.experiment import runner
    import agents

    agent = agents.get("q_learning_continuous")
    mdp = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=8, p_rand=0.1)
    g = runner.product([mdp], [agent.default_hparams], seeds=[0, 1])
    assert runner._band(g.mdps, g.mdp_index)[0] is not None
    banded = runner.run(agent, g, 1500, log_period=100, n_records=5)
    monkeypatch.setattr(runner, "_band", lambda mdps, index: (None, None))
    dense = runner.run(agent, g, 1500, log_period=100, n_records=5)
    np.testing.assert_array_equal(banded.steps, dense.steps)
    np.testing.assert_allclose(banded.values, dense.values, rtol=1e-5)


discounted_banded = jax.jit(dp.discounted_chain_values_banded, static_argnames=("bandwidth", "block"))


def _discounted64(P, deficit, r, gamma):
    """The float64 values of the system that a float32 computation holds: float32 off-diagonals, deficit and discount
    (0.999 is not a float32), the diagonal implied by ``1 - deficit - sum`` of the others."""
    P, deficit = np.asarray(np.float32(P), np.float64), np.asarray(np.float32(deficit), np.float64)
    off = P - np.diag(np.diag(P))
    implied = off + np.diag(1.0 - deficit - off.sum(1))
    return np.linalg.solve(np.eye(len(P)) - float(np.float32(gamma)) * implied, r)


@pytest.mark.parametrize("S,w,block", [(1, 0, 4), (13, 2, 1), (40, 5, 16), (61, 17, 3), (30, 29, 8)])
@pytest.mark.parametrize("gamma", [0.5, 0.99, 0.999])
def test_banded_discounted_values_solve_the_float64_system(S, w, block, gamma):
    # Sub-stochastic banded chains (the absorbing mass of band_chain is the deficit), three right-hand sides at once
    # and one alone.
    rng = np.random.default_rng(S + 7 * w)
    P, deficit = band_chain(rng, S, w)
    r = rng.normal(size=(S, 3))
    want = _discounted64(P, deficit, r, gamma)
    args = (jnp.asarray(P, jnp.float32), jnp.asarray(deficit, jnp.float32))
    got = np.asarray(discounted_banded(*args, jnp.asarray(r, jnp.float32), gamma, bandwidth=w, block=block))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * np.max(np.abs(want)))
    one = np.asarray(discounted_banded(*args, jnp.asarray(r[:, 1], jnp.float32), gamma, bandwidth=w, block=block))
    np.testing.assert_allclose(one, want[:, 1], rtol=0, atol=1e-6 * np.max(np.abs(want[:, 1])))


@pytest.mark.parametrize("up, leave", [(0.3, 1e-4), (0.001, 1e-3)])
def test_banded_discounted_values_stay_accurate_where_a_dense_solve_loses_digits(up, leave):
    # A river of 50 states that leaves only at its top, gamma = 1 - 1e-6: the float32 dense solve of I - gamma P
    # is off by about 1e-2; the elimination only adds non-negative numbers and stays within 1e-6.
    S, gamma = 50, 1.0 - 1e-6
    P = np.zeros((S, S))
    P[np.arange(S - 1), np.arange(1, S)] = up
    P[np.arange(1, S), np.arange(S - 1)] = 1.0 - up
    P[0, 0], P[-1, -1] = 1.0 - up, up - leave
    deficit = np.where(np.arange(S) == S - 1, leave, 0.0)
    want = _discounted64(P, deficit, np.ones(S), gamma)
    args = (jnp.asarray(P, jnp.float32), jnp.ones(S, jnp.float32), gamma)
    got = np.asarray(discounted_banded(args[0], jnp.asarray(deficit, jnp.float32), *args[1:], bandwidth=1))
    np.testing.assert_allclose(got, want, rtol=1e-6)
    dense = np.asarray(jax.jit(dp.discounted_chain_values)(*args))
    assert np.max(np.abs(dense / want - 1.0)) > 1e-3
