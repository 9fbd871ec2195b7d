"""The BlockMDP environment (paper §3.1, App. A.2): construction, reset/step, stacking and validation.

The central property: for the same keys, ``reset``/``step`` on a BlockMDP follow exactly the state trajectory of the
underlying MDP (same states, steps, rewards and flags) and return the emission-table row of the state reached plus one
noise draw from ``noise_key(key)``.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmdp
from jaxmdp.experiment.agent_interface import spec_of
from jaxmdp.blockmdp import noise_key
from jaxmdp.blockmdp.noise import sample_noise
from tests.conftest import random_mdp


@functools.cache
def simple_grid(episodic: bool) -> jaxmdp.MDP:
    # Random actions and Beta rewards, so that the trajectory depends on every draw of the MDP's stream.
    return jaxmdp.make("SimpleGrid", episodic=episodic, seed=1, size=4, p_rand=0.2, make_reward_stochastic=True)


@functools.cache
def deep_sea(size: int, episodic: bool = True) -> jaxmdp.MDP:
    return jaxmdp.make("DeepSea", episodic=episodic, seed=0, size=size)


@functools.partial(jax.jit, static_argnames="n")
def rollout(key, env, n):
    """``n`` steps of uniformly random actions from a reset; per-step records."""
    k_reset, k_steps = jax.random.split(key)
    obs, st = jaxmdp.reset(k_reset, env)

    def body(carry, k):
        obs, st = carry
        k_action, k_step = jax.random.split(k)
        a = jaxmdp.sample_action(k_action, env)
        obs2, st2, r, terminated, truncated, info = jaxmdp.step(k_step, st, a, env)
        rec = dict(obs=obs, state=st.state, h=st.h, action=a, reward=r, terminated=terminated, truncated=truncated,
                   next_obs=obs2, next_state=st2.state, next_h=st2.h, info=info, key=k_step)
        return (obs2, st2), rec

    (_, _), recs = jax.lax.scan(body, (obs, st), jax.random.split(k_steps, n))
    return recs


def table_rows(block, states, hs):
    table = np.asarray(block.emissions)
    return table[np.asarray(hs), np.asarray(states)] if block.episodic else table[np.asarray(states)]


NOISES = [(None, {}), ("gaussian", dict(scale=0.5)), ("correlated_student_t", dict(df=2.0))]


@pytest.mark.parametrize("noise, params", NOISES, ids=[str(n) for n, _ in NOISES])
@pytest.mark.parametrize("episodic", [False, True], ids=["continuous", "episodic"])
def test_state_trajectory_is_the_mdps_and_obs_are_table_rows_plus_noise(episodic, noise, params):
    m = simple_grid(episodic)
    block = jaxmdp.block_mdp(m, "state_info", noise, key=jax.random.key(9), **params)
    key, n = jax.random.key(5), 60
    plain, seen = rollout(key, m, n), rollout(key, block, n)
    for name in ("state", "h", "action", "reward", "terminated", "truncated", "next_state", "next_h"):
        np.testing.assert_array_equal(seen[name], plain[name], err_msg=name)
    np.testing.assert_array_equal(seen["info"]["final_state"], plain["info"]["final_observation"])
    np.testing.assert_array_equal(seen["info"]["discount"], plain["info"]["discount"])
    np.testing.assert_array_equal(seen["info"]["state"], plain["next_state"])
    if episodic:
        assert np.any(plain["terminated"])  # the episode boundary is exercised
    # The observation of the state reached: the table row plus the noise of noise_key(step key).
    rows = table_rows(block, seen["next_state"], seen["next_h"])
    if noise is None:
        np.testing.assert_array_equal(seen["next_obs"], rows)
    else:
        expected = rows + jax.vmap(
            lambda k: sample_noise(noise_key(k), noise, block.obs_shape, block.noise_scale, block.noise_df,
                                   block.noise_chol)
        )(seen["key"])
        np.testing.assert_allclose(seen["next_obs"], expected, rtol=0, atol=1e-6)
        assert np.min(np.abs(np.asarray(seen["next_obs"]) - rows)) > 0
    # final_observation: the very sample returned while the episode goes on; zeros after its last step.
    term = np.asarray(seen["terminated"])[:, None]
    np.testing.assert_array_equal(
        seen["info"]["final_observation"], np.where(term, 0.0, np.asarray(seen["next_obs"]))
    )
    # The first observation is the reset's.
    obs0, st0 = jaxmdp.reset(jax.random.split(key)[0], block)
    np.testing.assert_array_equal(seen["obs"][0], obs0)
    np.testing.assert_array_equal(obs0, jaxmdp.observe(noise_key(jax.random.split(key)[0]), block, st0.state, st0.h))


def test_observe_is_zero_past_the_episode():
    block = jaxmdp.block_mdp(deep_sea(4), "state_info", "gaussian")
    s = jnp.int32(0)
    assert np.all(np.asarray(jaxmdp.observe(jax.random.key(0), block, s, 4)) == 0.0)
    np.testing.assert_array_equal(jaxmdp.observe(None, jaxmdp.block_mdp(deep_sea(4)), s, 3), [3.0, 0.0, 3.0])


@pytest.mark.parametrize("emission", ["one_hot", "state_info", "tensor"])
def test_vmap_over_a_stacked_batch_matches_each_member(emission):
    # DeepSea 4 and 5 (S 10 / 15, H 4 / 5) share the state_info / tensor shapes only for the same size, so tensor
    # stacks two seeds' worth of the same size; one_hot (noiseless) pads the smaller one-hot vectors.
    mdps = [deep_sea(4), deep_sea(5)] if emission != "tensor" else [deep_sea(4), deep_sea(4)]
    noise, params = (None, {}) if emission == "one_hot" else ("gaussian", {})
    blocks = [
        jaxmdp.block_mdp(m, emission, noise, scale=s, **params) if noise else jaxmdp.block_mdp(m, emission)
        for m, s in zip(mdps, (0.1, 0.7))
    ]
    batch = jaxmdp.stack(blocks)
    keys = jax.random.split(jax.random.key(3), 2)
    together = jax.vmap(lambda k, b: rollout(k, b, 25))(keys, batch)
    for i, b in enumerate(blocks):
        alone = rollout(keys[i], b, 25)
        np.testing.assert_array_equal(together["next_state"][i], alone["next_state"])
        np.testing.assert_array_equal(together["reward"][i], alone["reward"])
        obs = np.asarray(together["next_obs"][i])
        if emission == "one_hot":  # padded with zeros beyond the member's own states
            assert np.all(obs[..., b.n_states :] == 0.0)
            obs = obs[..., : b.n_states]
        np.testing.assert_allclose(obs, alone["next_obs"], rtol=0, atol=1e-6)


def test_stack_and_unstack_round_trip():
    blocks = [
        jaxmdp.block_mdp(deep_sea(4), "state_info", "correlated_gaussian", key=jax.random.key(1)),
        jaxmdp.block_mdp(deep_sea(6), "state_info", "correlated_gaussian", key=jax.random.key(2), scale=0.3),
    ]
    batch = jaxmdp.stack(blocks)
    assert batch.emissions.shape == (2, 6, 21, 3) and batch.noise_chol.shape == (2, 3, 3)
    np.testing.assert_array_equal(batch.emissions[0, 4:], 0.0)  # steps past the member's horizon
    np.testing.assert_array_equal(batch.emissions[0, :, 10:], 0.0)  # padded states
    for orig, back in zip(blocks, jaxmdp.unstack(batch)):
        assert (back.emission_kind, back.noise_kind, back.obs_shape) == (orig.emission_kind, orig.noise_kind,
                                                                           orig.obs_shape)
        for name in ("emissions", "noise_scale", "noise_df", "noise_chol"):
            np.testing.assert_array_equal(getattr(back, name), getattr(orig, name), err_msg=name)
        np.testing.assert_array_equal(back.mdp.T, orig.mdp.T)
        assert back.mdp.info == orig.mdp.info


def test_one_hot_members_of_different_sizes_are_padded():
    small, big = (jaxmdp.block_mdp(jaxmdp.make("RiverSwim", episodic=False, seed=0, size=n), "one_hot") for n in (3, 5))
    batch = jaxmdp.stack([small, big])
    assert batch.obs_shape == (5,)
    np.testing.assert_array_equal(batch.emissions[0], np.eye(5) * (np.arange(5) < 3)[:, None])
    back = jaxmdp.unstack(batch)
    assert back[0].obs_shape == (3,)
    np.testing.assert_array_equal(back[0].emissions, np.eye(3))


def test_padded_observations_stack_members_of_different_shapes_and_carry_nothing_in_the_padding():
    # Episodic state_info: RiverSwim (h, X) has 2 components, DeepSea (h, X, Y) 3.
    river = jaxmdp.block_mdp(jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4), "state_info")
    sea = jaxmdp.block_mdp(deep_sea(4), "state_info")
    padded = jaxmdp.pad_observations(river, (3,))
    assert padded.obs_shape == (3,) and jaxmdp.pad_observations(sea, (3,)) is sea
    np.testing.assert_array_equal(padded.emissions[..., :2], river.emissions)
    np.testing.assert_array_equal(padded.emissions[..., 2], 0.0)
    np.testing.assert_array_equal(padded.obs_mask, [1.0, 1.0, 0.0])
    np.testing.assert_array_equal(spec_of(padded, 10).observation_mask, padded.obs_mask)
    assert spec_of(river, 10).observation_mask is None
    batch = jaxmdp.stack([padded, sea])
    np.testing.assert_array_equal(batch.obs_mask, [[1.0, 1.0, 0.0], [1.0, 1.0, 1.0]])
    keys = jax.random.split(jax.random.key(5), 2)
    together = jax.vmap(lambda k, b: rollout(k, b, 25))(keys, batch)
    for i, (b, width) in enumerate(((river, 2), (sea, 3))):
        alone = rollout(keys[i], b, 25)
        np.testing.assert_array_equal(together["next_state"][i], alone["next_state"])
        np.testing.assert_array_equal(together["next_obs"][i][..., :width], alone["next_obs"])
        np.testing.assert_array_equal(together["next_obs"][i][..., width:], 0.0)
    back = jaxmdp.unstack(batch)
    np.testing.assert_array_equal(back[0].obs_mask, padded.obs_mask)
    np.testing.assert_array_equal(back[0].emissions, padded.emissions)


def test_padded_observations_keep_the_noise_off_the_padding():
    # Gaussian noise of scale 0.5 on the two used components, none on the padding. Each used component's sample
    # variance over 4 000 draws is within 6 standard deviations (0.25 * 6 * sqrt(2 / 4000) = 0.034) of 0.25: a
    # false failure has probability below 1e-8.
    block = jaxmdp.block_mdp(jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4), "state_info", "gaussian",
                             scale=0.5)
    padded = jaxmdp.pad_observations(block, (4,))
    keys = jax.random.split(jax.random.key(9), 4000)
    obs = np.asarray(jax.vmap(lambda k: jaxmdp.observe(k, padded, jnp.int32(2), 1))(keys))
    np.testing.assert_array_equal(obs[:, 2:], 0.0)
    noise = obs[:, :2] - np.asarray(block.emissions[1, 2])
    assert np.all(np.abs(noise.var(axis=0) - 0.25) < 0.034), noise.var(axis=0)


def test_pad_observations_refusals():
    sea = jaxmdp.block_mdp(deep_sea(4), "state_info")
    with pytest.raises(ValueError, match=r"obs_shape must have the observation's rank \(1\) and be at least \(3,\)"):
        jaxmdp.pad_observations(sea, (2,))
    with pytest.raises(ValueError, match="rank"):
        jaxmdp.pad_observations(sea, (3, 1))
    with pytest.raises(ValueError, match="unbatched"):
        jaxmdp.pad_observations(jaxmdp.stack([sea, sea]), (4,))
    correlated = jaxmdp.block_mdp(deep_sea(4), "state_info", "correlated_gaussian", key=jax.random.key(1))
    with pytest.raises(ValueError, match="noise 'correlated_gaussian' is drawn with a covariance of the original"):
        jaxmdp.pad_observations(correlated, (4,))


def test_stack_errors():
    a = jaxmdp.block_mdp(deep_sea(4), "state_info")
    with pytest.raises(ValueError, match="cannot stack BlockMDPs with other objects"):
        jaxmdp.stack([a, deep_sea(4)])
    with pytest.raises(ValueError, match="different emission_kinds"):
        jaxmdp.stack([a, jaxmdp.block_mdp(deep_sea(4), "image")])
    with pytest.raises(ValueError, match="different noise_kinds"):
        jaxmdp.stack([a, jaxmdp.block_mdp(deep_sea(4), "state_info", "gaussian")])
    river = jaxmdp.block_mdp(jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4), "state_info")
    with pytest.raises(ValueError, match=r"different observation shapes: \[\(2,\), \(3,\)\]; pad them"):
        jaxmdp.stack([a, river])
    noisy = [jaxmdp.block_mdp(deep_sea(n), "one_hot", "gaussian") for n in (4, 5)]
    with pytest.raises(ValueError, match="different observation shapes"):
        jaxmdp.stack(noisy)
    with pytest.raises(ValueError, match="unbatched"):
        jaxmdp.stack([jaxmdp.stack([a, a]), a])


def test_block_fields_and_spec():
    block = jaxmdp.block_mdp(deep_sea(4), "image", "student_t", df=4)
    assert block.obs_shape == (5, 4) and block.emission_kind == "image" and block.noise_kind == "student_t"
    assert float(block.noise_df) == 4.0 and float(block.noise_scale) == 1.0 and block.noise_chol is None
    assert block.emissions.shape == (4, 10, 5, 4)
    leaves = jax.tree.leaves(block)
    assert any(leaf is block.noise_scale for leaf in leaves) and any(leaf is block.emissions for leaf in leaves)
    spec = spec_of(block, 100)
    assert spec.observations is block.emissions and (spec.n_states, spec.n_actions, spec.H) == (10, 2, 4)
    assert block.strip().info == jaxmdp.MDPInfo() and block.strip().obs_shape == block.obs_shape


def test_same_key_same_block():
    m = deep_sea(5, episodic=False)
    a, b, c = (jaxmdp.block_mdp(m, "linear_optimal", "correlated_gaussian", key=jax.random.key(k)) for k in (1, 1, 2))
    np.testing.assert_array_equal(a.emissions, b.emissions)
    np.testing.assert_array_equal(a.noise_chol, b.noise_chol)
    assert not np.allclose(a.noise_chol, c.noise_chol)
    # The table is emission_table's with the same key.
    np.testing.assert_array_equal(a.emissions, jaxmdp.emission_table(m, "linear_optimal", key=jax.random.key(1)))


def test_block_mdp_errors():
    m = deep_sea(4)
    with pytest.raises(ValueError, match="unknown emission 'state-info'; did you mean 'state_info'"):
        jaxmdp.block_mdp(m, "state-info")
    with pytest.raises(ValueError, match="unknown noise 'student'; did you mean 'student_t'"):
        jaxmdp.block_mdp(m, noise="student")
    with pytest.raises(ValueError, match="scale of noise 'gaussian' must be a positive finite number; got -1"):
        jaxmdp.block_mdp(m, noise="gaussian", scale=-1)
    with pytest.raises(ValueError, match="df of noise 'student_t' must be a positive finite number; got inf"):
        jaxmdp.block_mdp(m, noise="student_t", df=float("inf"))
    with pytest.raises(ValueError, match="noise 'gaussian' has no parameter 'df'"):
        jaxmdp.block_mdp(m, noise="gaussian", df=3)
    with pytest.raises(ValueError, match="without a noise kind"):
        jaxmdp.block_mdp(m, scale=0.1)
    with pytest.raises(ValueError, match="noise 'correlated_gaussian' draws its Wishart covariance .*pass key"):
        jaxmdp.block_mdp(m, noise="correlated_gaussian")
    with pytest.raises(ValueError, match="emission 'linear_random' draws random features: pass key"):
        jaxmdp.block_mdp(m, "linear_random")
    custom = random_mdp(np.random.default_rng(0), S=4, A=2)
    with pytest.raises(ValueError, match="emission 'image' needs .* kinds that work for any MDP: 'one_hot'"):
        jaxmdp.block_mdp(custom, "image")
    assert jaxmdp.block_mdp(custom, "one_hot").obs_shape == (4,)


def test_observe_errors():
    noisy = jaxmdp.block_mdp(deep_sea(4), "state_info", "gaussian")
    with pytest.raises(ValueError, match="observe needs a key to draw the 'gaussian' noise"):
        jaxmdp.observe(None, noisy, 0, 0)
    with pytest.raises(ValueError, match="expects an unbatched BlockMDP"):
        jaxmdp.observe(jax.random.key(0), jaxmdp.stack([noisy, noisy]), 0, 0)


@pytest.mark.nightly  # by default: test_vmap_over_a_stacked_batch_matches_each_member (values, not only shapes)
def test_jit_of_reset_and_step():
    block = jaxmdp.block_mdp(simple_grid(False), "tensor", "correlated_gaussian", key=jax.random.key(0))
    obs, st = jax.jit(jaxmdp.reset)(jax.random.key(1), block)
    assert obs.shape == block.obs_shape == (4, 4, 4)
    obs2, st2, *_ = jax.jit(jaxmdp.step)(jax.random.key(2), st, 1, block)
    assert obs2.shape == (4, 4, 4) and obs2.dtype == jnp.float32
    keys = jax.random.split(jax.random.key(3), 7)
    obs_v, st_v = jax.vmap(jaxmdp.reset, (0, None))(keys, block)
    assert obs_v.shape == (7, 4, 4, 4) and st_v.state.shape == (7,)
