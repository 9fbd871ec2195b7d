"""The MDP pytree: construction from arrays, validation errors, padding and stacking."""

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmdp

from conftest import random_mdp


def test_custom_mdp_from_mean_rewards():
    T = np.array([[[0.5, 0.5], [1.0, 0.0]], [[0.0, 1.0], [0.3, 0.7]]])
    R = np.array([[0.1, 0.2], [0.3, 0.4]])
    m = jaxmdp.custom_mdp(T, R, H=3)
    assert (m.n_states, m.n_actions, m.H, int(m.horizon)) == (2, 2, 3, 3)
    assert m.T.dtype == jnp.float32 and m.episodic
    np.testing.assert_allclose(m.R, R, rtol=1e-7)
    np.testing.assert_array_equal(m.P0, [1.0, 0.0])
    np.testing.assert_array_equal(m.reward_conc, 0.0)
    # successor lists reproduce T
    dense = np.zeros((2, 2, 2))
    np.add.at(dense, (np.arange(2)[:, None, None], np.arange(2)[None, :, None], np.asarray(m.succ)), m.succ_p)
    np.testing.assert_allclose(dense, T)


def test_custom_mdp_rewards_from_transition_means():
    T = np.array([[[0.25, 0.75]], [[1.0, 0.0]]])
    mean = np.array([[[0.2, 0.6]], [[0.5, 0.9]]])
    conc = np.array([[[2.0, 0.0]], [[4.0, 4.0]]])
    m = jaxmdp.custom_mdp(T, reward_mean=mean, reward_conc=conc)
    np.testing.assert_allclose(m.R, [[0.25 * 0.2 + 0.75 * 0.6], [0.5]], rtol=1e-6)
    np.testing.assert_allclose(m.reward_alpha[0, 0, 0], 0.4, rtol=1e-6)
    np.testing.assert_allclose(m.reward_beta[0, 0, 0], 1.6, rtol=1e-6)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(T=np.ones((2, 2))), r"T must have shape \[S, A, S\]"),
        (dict(T=np.ones((2, 1, 3)) / 3), r"T must have shape"),
        (dict(T=np.array([[[1.0, np.nan]], [[0, 1.0]]])), "T must be finite"),
        (dict(T=np.array([[[1.5, -0.5]], [[0, 1.0]]])), r"T must be non-negative; T\[0, 0, 1\]"),
        (dict(T=np.array([[[0.5, 0.4]], [[0, 1.0]]])), r"row \(s=0, a=0\) sums to 0.9"),
        (dict(R=np.zeros((3, 1))), r"R must have shape \(2, 1\)"),
        (dict(R=np.array([[np.inf], [0.0]])), "R must be finite"),
        (dict(P0=np.array([0.5, 0.6])), "P0 must be a probability distribution"),
        (dict(P0=np.ones(3) / 3), r"P0 must have shape \(2,\)"),
        (dict(H=0), "H must be an integer >= 1"),
        (dict(H=2.5), "H must be an integer >= 1"),
        (dict(reward_conc=-np.ones((2, 1, 2))), "reward_conc must be >= 0"),
    ],
)
def test_custom_mdp_rejects_bad_input(kwargs, match):
    args = dict(T=np.array([[[0.5, 0.5]], [[0.0, 1.0]]]), R=np.zeros((2, 1)))
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        jaxmdp.custom_mdp(**args)


def test_beta_reward_needs_mean_inside_unit_interval():
    T = np.array([[[1.0]]])
    with pytest.raises(ValueError, match="strictly inside"):
        jaxmdp.custom_mdp(T, reward_mean=np.ones((1, 1, 1)), reward_conc=np.ones((1, 1, 1)))


def test_stack_pads_without_changing_members():
    rng = np.random.default_rng(0)
    mdps = [random_mdp(rng, 3, 2, H=4), random_mdp(rng, 5, 4, H=6), random_mdp(rng, 4, 3, H=2)]
    batch = jaxmdp.stack(mdps)
    assert batch.T.shape == (3, 5, 4, 5) and batch.H == 6
    np.testing.assert_array_equal(batch.horizon, [4, 6, 2])
    np.testing.assert_array_equal(batch.state_mask[0], [1, 1, 1, 0, 0])
    np.testing.assert_array_equal(batch.action_mask[0], [1, 1, 0, 0])
    # padded states are absorbing and unreachable; padded actions copy action 0
    T0 = np.asarray(batch.T[0])
    np.testing.assert_array_equal(T0[3:, :, 3:], np.broadcast_to(np.eye(2)[:, None, :], (2, 4, 2)))
    np.testing.assert_array_equal(T0[:3, :, 3:], 0.0)
    np.testing.assert_array_equal(T0[:3, 2], T0[:3, 0])
    back = jaxmdp.unstack(batch)
    for a, b in zip(mdps, back):
        for name in ("T", "R", "P0", "reward_mean", "reward_conc", "succ", "succ_p", "state_mask", "action_mask"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert b.H == a.H and b.stochastic_rewards == a.stochastic_rewards


def test_stack_rejects_mixed_settings():
    rng = np.random.default_rng(1)
    with pytest.raises(ValueError, match="episodic and continuous"):
        jaxmdp.stack([random_mdp(rng, 3, 2, H=3), random_mdp(rng, 3, 2)])


def test_strip_shares_compilations():
    a = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5)
    b = jaxmdp.make("RiverSwim", episodic=False, seed=1, size=5)
    assert a.info != b.info
    assert jax.tree.structure(a.strip()) == jax.tree.structure(b.strip())


def test_registry_suggests_close_names_and_parameters():
    assert set(jaxmdp.families()) == {
        "RiverSwim", "DeepSea", "SimpleGrid", "FrozenLake", "MiniGridEmpty", "MiniGridRooms", "Taxi", "MiniGridDoorKey"
    }
    with pytest.raises(ValueError, match="did you mean 'RiverSwim'"):
        jaxmdp.make("RiverSwin", episodic=False, seed=0, size=5)
    with pytest.raises(ValueError, match="has no parameter 'sise'; did you mean 'size'"):
        jaxmdp.make("RiverSwim", episodic=False, seed=0, sise=5)


def test_register_custom_family():
    def two_state(*, episodic, seed, reward=1.0):
        T = np.array([[[0.0, 1.0]], [[1.0, 0.0]]])
        return jaxmdp.custom_mdp(T, np.array([[reward], [0.0]]), H=2 if episodic else None)

    jaxmdp.register("TwoStateTest", two_state, overwrite=True)
    m = jaxmdp.make("TwoStateTest", episodic=True, seed=0, reward=0.5)
    np.testing.assert_allclose(jaxmdp.optimal_value(m), 0.5)
    with pytest.raises(ValueError, match="already registered"):
        jaxmdp.register("TwoStateTest", two_state)


def _partitions(n, k):
    """Every split of range(n) into at most k contiguous non-empty runs, as lists of cut points."""
    for m in range(1, k + 1):
        for cuts in itertools.combinations(range(1, n), m - 1):
            yield [0, *cuts, n]


def test_size_buckets_minimise_padded_work_brute_force():
    rng = np.random.default_rng(5)
    for trial in range(4):
        episodic = trial % 2 == 1
        shapes = [(int(rng.integers(2, 9)), int(rng.integers(1, 4))) for _ in range(7)]
        mdps = [random_mdp(rng, S, A, H=int(rng.integers(2, 6)) if episodic else None) for S, A in shapes]
        dims = np.array([(m.n_states, m.n_actions, m.max_successors, m.H or 1) for m in mdps], float)
        order = np.lexsort(dims.T[::-1])

        def work(group):
            top = dims[group].max(axis=0)
            return len(group) * top[0] ** 2 * top[1] * top[2] * top[3]

        for k in (1, 2, 3):
            groups = jaxmdp.size_buckets(mdps, k)
            assert len(groups) <= k and sorted(i for g in groups for i in g) == list(range(7))
            brute = min(
                sum(work(order[a:b]) for a, b in zip(cuts, cuts[1:])) for cuts in _partitions(7, k)
            )
            assert sum(work(g) for g in groups) == brute
    assert len(jaxmdp.size_buckets(mdps, 1)) == 1


def test_size_buckets_rejects_bad_input():
    rng = np.random.default_rng(6)
    with pytest.raises(ValueError, match="n_buckets"):
        jaxmdp.size_buckets([random_mdp(rng, 3, 2)], 0)
    with pytest.raises(ValueError, match="all episodic or all continuous"):
        jaxmdp.size_buckets([random_mdp(rng, 3, 2, H=3), random_mdp(rng, 3, 2)], 2)
