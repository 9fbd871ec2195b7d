"""Kernel transforms p_rand / p_lazy: hand-worked rows, equality with from-scratch construction, NaN policy."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmdp


def test_river_swim_worked_example_rows():
    # docs/families.md §2.1: size 5, no randomisation, p_lazy 0.1, p_rand 0.2.
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, randomize_actions=False, p_lazy=0.1, p_rand=0.2)
    T, R = np.asarray(m.T), np.asarray(m.R)
    np.testing.assert_allclose(T[0, 0, :2], [0.91, 0.09], rtol=1e-6)  # LEFT at X=0
    np.testing.assert_allclose(T[0, 1, :2], [0.19, 0.81], rtol=1e-6)  # RIGHT at X=0
    np.testing.assert_allclose(T[4, 1, 3:], [0.09, 0.91], rtol=1e-6)  # RIGHT at X=4
    np.testing.assert_allclose(R[[0, 0, 4], [0, 1, 1]], [0.005, 0.0, 1.0], rtol=1e-6)


@pytest.mark.parametrize("p_rand, p_lazy", [(0.2, 0.0), (0.0, 0.3), (0.15, 0.25)])
def test_transform_equals_construction_from_scratch(p_rand, p_lazy):
    kw = dict(episodic=False, seed=0, size=7, randomize_actions=False, make_reward_stochastic=True)
    base = jaxmdp.make("RiverSwim", **kw)
    direct = jaxmdp.make("RiverSwim", p_rand=p_rand or None, p_lazy=p_lazy or None, **kw)
    moved = jaxmdp.apply_noise(base, p_rand, p_lazy)
    moved = jaxmdp.permute_states(moved, jaxmdp.state_permutation(moved, direct))
    np.testing.assert_allclose(moved.T, direct.T, atol=1e-7)
    np.testing.assert_allclose(moved.R, direct.R, atol=1e-7)
    # the successor lists describe the same kernel
    S, A, _ = moved.succ.shape
    dense = np.zeros((S, A, S))
    np.add.at(dense, (np.arange(S)[:, None, None], np.arange(A)[None, :, None], np.asarray(moved.succ)), moved.succ_p)
    np.testing.assert_allclose(dense, direct.T, atol=1e-6)


def test_sweep_is_one_vmap_over_a_base_mdp():
    base = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=6, randomize_actions=False)
    grid = jnp.linspace(0.0, 0.8, 5)
    swept = jax.jit(jax.vmap(jaxmdp.apply_p_rand, in_axes=(None, 0)))(base.strip(), grid)
    for i, r in enumerate(np.asarray(grid)):
        one = jaxmdp.apply_p_rand(base, float(r))
        np.testing.assert_allclose(swept.T[i], one.T, atol=1e-7)
        np.testing.assert_allclose(swept.R[i], one.R, atol=1e-7)


def test_transform_respects_padded_actions():
    rng = np.random.default_rng(0)
    T = rng.dirichlet(np.ones(3), size=(3, 2))
    small = jaxmdp.custom_mdp(T, rng.random((3, 2)))
    padded = jaxmdp.pad(small, 4, 3, small.max_successors)
    a = jaxmdp.apply_p_rand(small, 0.5)
    b = jaxmdp.apply_p_rand(padded, 0.5)
    np.testing.assert_allclose(b.T[:3, :2, :3], a.T, atol=1e-7)
    np.testing.assert_allclose(b.T[:3, 2], b.T[:3, 0], atol=1e-7)


def test_invalid_probabilities():
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=3)
    for bad in (-0.1, 0.9999, 1.5):
        with pytest.raises(ValueError, match="p_rand must lie in"):
            jaxmdp.apply_p_rand(m, bad)
        with pytest.raises(ValueError, match="p_lazy must lie in"):
            jaxmdp.apply_p_lazy(m, bad)
    # Traced values cannot raise: the documented NaN policy applies.
    out = jax.jit(jaxmdp.apply_p_lazy)(m.strip(), 1.2)
    assert bool(jnp.all(jnp.isnan(out.T)))
    with pytest.raises(ValueError, match="p_lazy must lie in"):
        jaxmdp.make("RiverSwim", episodic=False, seed=0, size=3, p_lazy=1.0)
