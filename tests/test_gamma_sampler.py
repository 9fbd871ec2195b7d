"""The Gamma sampler's parts and guarantees: the fused Threefry against ``jax.random``'s, compaction against numpy,
exactness against scipy on the compacted path and on the overflow path (tiny buffers), batch invariance (bitwise),
same key / same value, bad input. Beta draws and scalar shapes: tests/test_reward_sampling.py."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import special, stats

import jaxmdp.beta_sampling as bs
from jaxmdp.beta_sampling import buffer_sizes, sample_beta, sample_log_gamma
from jaxmdp.compaction import compact
from jaxmdp.threefry import key_words, threefry2x32, unit_float

SHAPES = (0.01, 0.32, 1.0, 5.0, 100.0)
PER_SHAPE = 40_000


# ---------------------------------------------------------------------------------------------------------------
# Threefry and uniforms
# ---------------------------------------------------------------------------------------------------------------


def test_threefry_matches_jax():
    edge = [0, 1, 7, 2**31 - 1, 2**31, 2**32 - 1]
    hi = jnp.array(np.repeat(edge, len(edge)), jnp.uint32)
    lo = jnp.array(np.tile(edge, len(edge)), jnp.uint32)
    for key in (jax.random.key(0), jax.random.key(12345), jax.random.key(2**31 + 5)):
        kd = jax.random.key_data(key)
        ref = np.asarray(jax.extend.random.threefry_2x32(kd, jnp.concatenate([hi, lo])))  # halves: (hi, lo) pairs
        w0, w1 = jax.jit(threefry2x32)(kd[0], kd[1], hi, lo)
        np.testing.assert_array_equal(np.concatenate([w0, w1]), ref)


def test_key_words_is_fold_in():
    for key in (jax.random.key(3), jax.random.PRNGKey(3)):  # typed and raw Threefry keys
        for tag in (0, 5, 2**31 - 1):
            np.testing.assert_array_equal(np.array(jax.jit(key_words, static_argnums=1)(key, tag)),
                                          jax.random.key_data(jax.random.fold_in(key, tag)))
    rbg = jax.random.key(3, impl="rbg")  # other implementations: two words drawn from fold_in(key, tag)
    words = np.array(key_words(rbg, 5))
    np.testing.assert_array_equal(words, jax.random.bits(jax.random.fold_in(rbg, 5), (2,), jnp.uint32))
    assert not np.array_equal(words, np.array(key_words(rbg, 6)))


def test_unit_float_is_jax_uniform_grid():
    words = jnp.array([0, 1 << 9, (1 << 9) - 1, 2**32 - 1], jnp.uint32)
    np.testing.assert_array_equal(unit_float((words,), jnp.float32), [0.0, 2.0**-23, 0.0, 1.0 - 2.0**-23])
    # The same conversion as jax.random.uniform: equal on the words jax.random.bits gives.
    key = jax.random.key(9)
    np.testing.assert_array_equal(unit_float((jax.random.bits(key, (1000,), jnp.uint32),), jnp.float32),
                                  jax.random.uniform(key, (1000,)))
    with jax.enable_x64(True):
        hi = jnp.array([0, 2**32 - 1, 0], jnp.uint32)
        lo = jnp.array([0, 2**32 - 1, 1 << 12], jnp.uint32)
        np.testing.assert_array_equal(unit_float((hi, lo), jnp.float64), [0.0, 1.0 - 2.0**-52, 2.0**-52])


def test_erfinv_midpoint_on_every_cell():
    # All 2^23 float32 uniforms: erfinv at the cell midpoints (2k + 1) 2^-24 against scipy in float64.
    k = np.arange(2**23, dtype=np.float64)
    ref = special.erfinv((2 * k + 1) * 2.0**-23 - 1.0)
    got = np.asarray(jax.jit(bs._erfinv_midpoint)(jnp.asarray(k * 2.0**-23, jnp.float32)), np.float64)
    assert np.max(np.abs(got - ref) / np.abs(ref)) < 3e-7
    np.testing.assert_array_equal(got, -got[::-1])  # symmetric: N(0, 1) deviates with mean exactly 0 over the grid
    with jax.enable_x64(True):
        u = jnp.array([0.0, 0.5, 1.0 - 2.0**-52], jnp.float64)
        np.testing.assert_allclose(bs._erfinv_midpoint(u), special.erfinv(2 * (np.asarray(u) + 2.0**-53) - 1),
                                   rtol=1e-14)


# ---------------------------------------------------------------------------------------------------------------
# Compaction
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n, p", [(1, 1.0), (31, 0.5), (32, 0.0), (33, 1.0), (1000, 0.05), (5000, 0.3)])
def test_compact_matches_nonzero(n, p):
    flags = np.random.default_rng(n).random(n) < p
    true = np.flatnonzero(flags)
    for size in sorted({1, 7, max(len(true), 1), n + 3}):
        index, valid = jax.jit(compact, static_argnums=1)(jnp.asarray(flags), size)
        count = min(size, len(true))
        np.testing.assert_array_equal(valid, np.arange(size) < count)
        np.testing.assert_array_equal(index[:count], true[:count])
        np.testing.assert_array_equal(index[count:], n + np.arange(count, size))  # distinct, out of range


def test_compact_under_vmap_is_per_member():
    flags = jnp.asarray(np.random.default_rng(0).random((4, 700)) < np.array([[0.0], [0.01], [0.2], [1.0]]))
    index, valid = jax.jit(jax.vmap(compact, (0, None)), static_argnums=1)(flags, 50)
    for i in range(4):
        single = compact(flags[i], 50)
        np.testing.assert_array_equal(index[i], single[0])
        np.testing.assert_array_equal(valid[i], single[1])


# ---------------------------------------------------------------------------------------------------------------
# Exactness (scipy)
# ---------------------------------------------------------------------------------------------------------------


def assert_log_gamma(y: np.ndarray, a: float) -> None:
    """``y`` are i.i.d. ``ln G``, ``G ~ Gamma(a)``: KS in log space, E = digamma(a), Var = trigamma(a) (6 SE)."""
    k = y.size
    assert np.all(np.isfinite(y)), a
    assert stats.kstest(y, lambda t: stats.gamma.cdf(np.exp(t), a)).pvalue > 1e-3, a
    var = special.polygamma(1, a)
    assert abs(y.mean() - special.digamma(a)) < 6 * np.sqrt(var / k), a
    # Var of the sample variance: (mu_4 - sigma^4) / k with mu_4 = psi_3 + 3 psi_1^2 (cumulants of ln G).
    assert abs(y.var() - var) < 6 * np.sqrt((special.polygamma(3, a) + 2 * var**2) / k), a


@functools.lru_cache(maxsize=None)
def mixed_draws(buffers):
    """One draw of an array holding every shape of ``SHAPES`` ``PER_SHAPE`` times, interleaved at random."""
    a = np.repeat(np.array(SHAPES, np.float32), PER_SHAPE)[np.random.default_rng(1).permutation(len(SHAPES) * PER_SHAPE)]
    y = jax.jit(functools.partial(sample_log_gamma, buffers=buffers))(jax.random.key(11), jnp.asarray(a))
    return a, np.asarray(y, np.float64)


@pytest.mark.parametrize("buffers", [None, (64, 1)], ids=["default", "overflow"])
def test_log_gamma_exact_on_large_arrays(buffers):
    a, y = mixed_draws(buffers)
    m1, m2 = buffer_sizes(a.size) if buffers is None else buffers
    assert m1 < a.size  # the compacted path
    # First-round rejections: fewer than m1 by far with the default buffers, far more with the tiny ones (so the
    # pass loop, with both buffers overflowing, did the work).
    seed = key_words(jax.random.key(11), bs._STREAM)
    first = bs._trial(seed, jnp.zeros(a.size, jnp.uint32), jnp.arange(a.size, dtype=jnp.uint32),
                      bs._shape_terms(jnp.asarray(a)))
    rejected = int(jnp.isnan(first).sum())
    assert (rejected < m1 // 2) if buffers is None else (rejected > 50 * m1)
    for shape in SHAPES:
        ys = y[a == np.float32(shape)]
        assert_log_gamma(ys, shape)
        # Entries are independent: neighbours (in array order) uncorrelated.
        assert abs(np.corrcoef(ys[:-1], ys[1:])[0, 1]) < 5 / np.sqrt(ys.size), shape


@pytest.mark.parametrize("candidates", [None, 1])
def test_log_gamma_exact_on_small_arrays(candidates):
    # A 5-entry array is below the compaction size: whole-array rounds, vmapped over keys.
    keys = jax.random.split(jax.random.key(12), 20_000)
    f = jax.jit(jax.vmap(functools.partial(sample_log_gamma, candidates=candidates), (0, None)))
    y = np.asarray(f(keys, jnp.array(SHAPES)), np.float64)
    for i, shape in enumerate(SHAPES):
        assert_log_gamma(y[:, i], shape)


def test_float64_and_bfloat16():
    with jax.enable_x64(True):
        a = jnp.repeat(jnp.array([0.32, 5.0], jnp.float64), 30_000)
        y = jax.jit(functools.partial(sample_log_gamma, dtype=jnp.float64))(jax.random.key(13), a)
        assert y.dtype == jnp.float64
        y = np.asarray(y)
        assert_log_gamma(y[:30_000], 0.32)
        assert_log_gamma(y[30_000:], 5.0)
    y = sample_log_gamma(jax.random.key(13), jnp.full((20_000,), 5.0), dtype=jnp.bfloat16)
    assert y.dtype == jnp.bfloat16
    assert abs(float(y.astype(jnp.float32).mean()) - special.digamma(5.0)) < 0.01


# ---------------------------------------------------------------------------------------------------------------
# Determinism and batches
# ---------------------------------------------------------------------------------------------------------------


def posterior_like(S: int, A: int, seed: int) -> jnp.ndarray:
    """A Dirichlet posterior concentration ``1/S + counts`` (mostly shapes below one)."""
    counts = np.random.default_rng(seed).poisson(0.3, (S, A, S))
    return jnp.asarray(1.0 / S + counts, jnp.float32)


@pytest.mark.parametrize("in_axes, buffers", [((0, None), None), ((0, 0), (16, 1))],
                         ids=["shared-shapes-default", "own-shapes-overflow"])
def test_vmap_member_equals_single_call_bitwise(in_axes, buffers):
    alpha = posterior_like(20, 3, 0)  # 1200 entries: compacted (m1 = 139)
    keys = jax.random.split(jax.random.key(14), 3)
    f = functools.partial(sample_log_gamma, buffers=buffers)
    arg = alpha if in_axes[1] is None else jnp.stack([alpha] * 3)
    batched = np.asarray(jax.jit(jax.vmap(f, in_axes))(keys, arg))
    single = jax.jit(f)
    for i in range(3):
        np.testing.assert_array_equal(batched[i], single(keys[i], alpha))


def test_eager_call_equals_jitted_bitwise():
    alpha = posterior_like(20, 3, 2)
    keys = jax.random.split(jax.random.key(21), 2)
    batched = jax.jit(jax.vmap(sample_log_gamma, (0, None)))(keys, alpha)
    np.testing.assert_array_equal(batched[1], sample_log_gamma(keys[1], alpha))


def test_small_arrays_and_beta_vmap_equal_single_calls_bitwise():
    keys = jax.random.split(jax.random.key(15), 64)
    a = jax.random.uniform(jax.random.key(16), (64,), minval=0.005, maxval=6.0)
    b = jax.random.uniform(jax.random.key(17), (64,), minval=0.005, maxval=6.0)
    batched = jax.jit(jax.vmap(sample_beta))(keys, a, b)
    small = jax.jit(jax.vmap(sample_log_gamma, (0, None)))(keys, jnp.array(SHAPES))
    for i in range(0, 64, 7):
        assert float(batched[i]) == float(sample_beta(keys[i], a[i], b[i]))
        np.testing.assert_array_equal(small[i], sample_log_gamma(keys[i], jnp.array(SHAPES)))


def test_same_key_same_value_other_key_other_value():
    alpha = posterior_like(12, 2, 1)
    y1 = sample_log_gamma(jax.random.key(18), alpha)
    np.testing.assert_array_equal(y1, jax.jit(sample_log_gamma)(jax.random.key(18), alpha))
    y2 = sample_log_gamma(jax.random.key(19), alpha)
    assert np.mean(np.asarray(y1) != np.asarray(y2)) > 0.999
    # The sampler's stream is its own: drawing it does not repeat what the key gives jax.random.
    u = unit_float((jax.random.bits(jax.random.key(18), (alpha.size,), jnp.uint32),), jnp.float32)
    assert np.corrcoef(np.asarray(u), np.asarray(y1).ravel())[0, 1] < 0.1


# ---------------------------------------------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------------------------------------------


def test_improper_shapes_give_limits_or_nan_and_never_hang():
    a = jnp.array([0.0, -1.0, jnp.nan, jnp.inf, 1e-42, 1e30, 0.5], jnp.float32)
    y = np.asarray(sample_log_gamma(jax.random.key(20), a))
    assert y[0] == -np.inf and np.isnan(y[1]) and np.isnan(y[2]) and y[3] == np.inf
    assert y[4] < -1e30  # subnormal shape: ln G ~ ln(U) / a, -inf in float32 or close to it
    assert abs(y[5] - np.log(1e30)) < 1e-5 and np.isfinite(y[6])
    # The same inside a large (compacted) array: the bad entries do not block the loops.
    big = jnp.tile(a, 300)
    yb = np.asarray(sample_log_gamma(jax.random.key(20), big)).reshape(300, -1)
    assert np.all(np.isnan(yb[:, 1:3])) and np.all(yb[:, 0] == -np.inf) and np.all(np.isfinite(yb[:, 5:]))


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="candidates"):
        sample_log_gamma(jax.random.key(0), jnp.ones(3), candidates=0)
    with pytest.raises(ValueError, match="buffers"):
        sample_log_gamma(jax.random.key(0), jnp.ones(300), buffers=(0, 1))
    assert sample_log_gamma(jax.random.key(0), jnp.ones((0, 3))).shape == (0, 3)
