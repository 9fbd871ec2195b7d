"""The Gamma sampler's parts and guarantees: compaction against numpy, exactness against scipy (KS, moments) on the
compacted path, the overflow path (tiny buffers) and whole-array rounds, float32 and float64, batch invariance
(bitwise), same key / same value, bad input. More Beta draws and scalar shapes: tests/test_reward_sampling.py."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import jaxmdp.sampling.beta_sampling as bs
from jaxmdp.sampling.beta_sampling import buffer_sizes, sample_beta, sample_log_gamma
from jaxmdp.sampling.compaction import compact, compact_with_count
from stat_checks import Checks, key
from stat_checks import seed as stat_seed

SHAPES = (0.01, 0.32, 1.0, 5.0, 100.0, 1e4)
PER_SHAPE = 40_000


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
        with_count = jax.jit(compact_with_count, static_argnums=1)(jnp.asarray(flags), size)
        np.testing.assert_array_equal(with_count[0], index)
        assert int(with_count[2]) == len(true)  # all of them, also past size


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


QUANTILES = (1e-3, 0.02, 0.25, 0.5, 0.75, 0.98, 0.999)


def assert_log_gamma(checks: Checks, y: np.ndarray, a: float) -> None:
    """``y`` are i.i.d. ``ln G``, ``G ~ Gamma(a)``: KS against scipy's log-Gamma CDF (no underflow for tiny shapes),
    counts below 7 exact quantiles (Binomial; the far tails check the spread, the median the location), and for
    ``a >= 0.3`` the sum of ``G``, exactly Gamma(k a). 9 checks (8 below 0.3), each failing a correct sampler with
    probability <= 1e-7 (tests/stat_checks.py)."""
    assert np.all(np.isfinite(y)), a
    ref = stats.loggamma(a)
    checks.ks(y, ref.cdf, f"ln G, shape {a}")
    checks.below_quantiles(y, ref.ppf, QUANTILES, f"ln G, shape {a}")
    if a >= 0.3:  # below, the sum of G is dominated by rare large draws and says little
        checks.gamma_sum(np.exp(y).sum(), y.size * a, f"sum of G, shape {a}")


@functools.lru_cache(maxsize=2)
def mixed_draws(buffers, seed):
    """One draw of an array holding every shape of ``SHAPES`` ``PER_SHAPE`` times, interleaved at random."""
    a = np.repeat(np.array(SHAPES, np.float32), PER_SHAPE)[np.random.default_rng(1).permutation(len(SHAPES) * PER_SHAPE)]
    y = sample_log_gamma(jax.random.key(seed), jnp.asarray(a), buffers=buffers)  # jitted, buffers static
    return a, np.asarray(y, np.float64)


@pytest.mark.statistical(p=5.6e-6)
@pytest.mark.parametrize("buffers", [None, (64, 1)], ids=["default", "overflow"])
def test_log_gamma_exact_on_large_arrays(buffers):
    # 6 shapes x (8 or 9 checks + 1 independence check): 56 checks, false-failure probability <= 5.6e-6 for the
    # test and 1e-7 per assertion.
    seed = stat_seed(11)
    a, y = mixed_draws(buffers, seed)
    m1, m2 = buffer_sizes(a.size) if buffers is None else buffers
    assert m1 < a.size  # the compacted path
    # First-round rejections: fewer than m1 by far with the default buffers, far more with the tiny ones (so the
    # pass loop, with both buffers overflowing, did the work). Not a statistical check: the margins are wide (a
    # factor two or more either way at the sampler's acceptance rates).
    stream = jax.random.fold_in(jax.random.key(seed), bs._STREAM)
    first = bs._trial(jax.random.fold_in(stream, 0), bs.shape_terms(jnp.asarray(a)))
    rejected = int(jnp.isnan(first).sum())
    assert (rejected < m1 // 2) if buffers is None else (rejected > 50 * m1)
    checks = Checks()
    for shape in SHAPES:
        ys = y[a == np.float32(shape)]
        assert_log_gamma(checks, ys, shape)
        # Entries are independent: disjoint neighbour pairs on the same side of the exact median, Binomial(k/2, 1/2).
        median = stats.loggamma(shape).median()
        checks.independent_signs(ys[0:-1:2], ys[1::2], median, median, f"neighbours, shape {shape}")


@pytest.mark.nightly  # a corner of the buffer; by default: test_log_gamma_exact_on_large_arrays
@pytest.mark.parametrize("which", ["first", "second"])
def test_an_overflowing_buffer_sends_its_entries_to_another_pass(which):
    # The compacted pass reports an overflow from the compactions' counts; then further passes finish the entries
    # it left. "first": both buffers overflow; "second": only the second one (its m2 = 1 slot holds one of
    # the first buffer's rejections, far fewer than m1 = 400 first-round rejections at most). Without the flag (or
    # with one buffer's count left out) entries stay NaN.
    a = jnp.asarray(np.random.default_rng(3).uniform(0.05, 3.0, 8000), jnp.float32)
    buffers = (16, 1) if which == "first" else (400, 1)
    k = jax.random.key(31)
    stream = jax.random.fold_in(k, bs._STREAM)
    first = bs._trial(jax.random.fold_in(stream, 0), bs.shape_terms(a))
    rejected = int(jnp.isnan(first).sum())
    assert (rejected > 16) if which == "first" else (40 < rejected < 400)  # about 4% of 8000: wide margins
    # The first pass (key fold_in(stream, 1)) leaves entries NaN and says so; with the default buffers it does not.
    for m, overflow in ((buffers, True), (buffer_sizes(a.size), False)):
        after, left = bs._compacted_pass(jax.random.fold_in(stream, 1), first, a, *m)
        assert bool(left) == overflow == bool(jnp.isnan(after).any())
    y = np.asarray(sample_log_gamma(k, a, buffers=buffers))
    assert np.all(np.isfinite(y))
    default = np.asarray(sample_log_gamma(k, a))
    accepted = ~np.isnan(np.asarray(first))
    np.testing.assert_array_equal(y[accepted], default[accepted])  # the first round's values are kept


@pytest.mark.statistical(p=5.3e-6)
@pytest.mark.parametrize("candidates", [None, 1])
def test_log_gamma_exact_on_small_arrays(candidates):
    # A 6-entry array is below the compaction size: whole-array rounds, vmapped over keys. 53 checks: <= 5.3e-6.
    y = np.asarray(small_array_draws(key(12), candidates), np.float64)
    checks = Checks()
    for i, shape in enumerate(SHAPES):
        assert_log_gamma(checks, y[:, i], shape)


@functools.partial(jax.jit, static_argnames="candidates")
def small_array_draws(k, candidates):
    f = jax.vmap(functools.partial(sample_log_gamma, candidates=candidates), (0, None))
    return f(jax.random.split(k, 20_000), jnp.array(SHAPES))


@pytest.mark.nightly  # other dtypes of the default float32 tests
@pytest.mark.statistical(p=3.6e-6)
def test_float64_and_bfloat16():
    # float64: 4 shapes, 34 checks; bfloat16: 2 binomial counts. False-failure probability <= 3.6e-6 (1e-7 each).
    shapes = (0.01, 0.32, 5.0, 1e4)
    checks = Checks()
    with jax.enable_x64(True):
        a = jnp.repeat(jnp.array(shapes, jnp.float64), 30_000)
        y = sample_log_gamma(key(13), a, dtype=jnp.float64)  # (sample_log_gamma is jitted, dtype static)
        assert y.dtype == jnp.float64
        y = np.asarray(y).reshape(len(shapes), -1)
        for i, shape in enumerate(shapes):
            assert_log_gamma(checks, y[i], shape)
    y = sample_log_gamma(key(14), jnp.full((20_000,), 5.0), dtype=jnp.bfloat16)
    assert y.dtype == jnp.bfloat16
    # bfloat16 draws are float32 draws rounded to nearest: at a bfloat16 number q, y <= q iff the float32 draw is at
    # most q + ulp(q) / 2, so the count below q is exactly Binomial(n, F(q + ulp / 2)).
    ref = stats.loggamma(5.0)
    y = np.asarray(y.astype(jnp.float32), np.float64)
    for p in (0.1, 0.9):
        q = float(jnp.bfloat16(ref.ppf(p)))
        ulp = 2.0 ** (np.floor(np.log2(abs(q))) - 7)
        checks.binomial(int(np.sum(y <= q)), y.size, ref.cdf(q + ulp / 2), f"bfloat16 below {q}")


@pytest.mark.parametrize("bits", [32, 64])
def test_deviates_from_extreme_words_are_finite_and_exact(bits):
    # The lowest and highest words give the grid's ends, by hand: v = -1 (moved up to the next float, as erf_inv(-1)
    # is infinite) and 1 - 2^(2 - m) with m the mantissa bits + 1; w = 1 and 2^(1 - m). Every deviate is finite.
    dtype, uint, m = (jnp.float32, np.uint32, 24) if bits == 32 else (jnp.float64, np.uint64, 53)
    with jax.enable_x64(bits == 64):
        words = jnp.array([0, np.iinfo(uint).max], uint)
        e, w = jax.jit(bs.deviates_from_words)(words, words)
        e, w = np.asarray(e), np.asarray(w)
        np_dtype = np.dtype(dtype)
        lo = np.nextafter(np_dtype.type(-1.0), np_dtype.type(0.0))
        ref = jax.lax.erf_inv(jnp.array([lo, 1.0 - 2.0 ** (2 - m)], dtype))
    assert e.dtype == np_dtype and w.dtype == np_dtype and np.all(np.isfinite(e))
    np.testing.assert_array_equal(e, np.asarray(ref))
    np.testing.assert_array_equal(w, np.array([1.0, 2.0 ** (1 - m)], np_dtype))


@functools.partial(jax.jit, static_argnames="dtype")
def beta_draws(keys, a, b, dtype):
    return jax.vmap(lambda k: sample_beta(k, a, b, dtype=dtype))(keys)


@pytest.mark.statistical(p=5e-6)
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_beta_against_scipy(dtype):
    # Beta(0.01, 0.5) puts 41% of its mass below 1e-38, where float32 rounds to 0: the fraction below 1e-30 is checked
    # against scipy's CDF (binomial), the rest by KS against scipy's conditional CDF; mean and variance by Bernstein
    # (bounded in [0, 1]); counts below 7 exact quantiles above the tiny mass. 4 x (1 + 1 + 2 + up to 7) < 50 checks:
    # false-failure probability <= 5e-6 for the test, 1e-7 per assertion.
    params = ((0.01, 0.5), (0.5, 0.5), (2.0, 50.0), (300.0, 7.0))
    tiny = 1e-30
    checks = Checks()
    with jax.enable_x64(dtype == "float64"):
        keys = jax.random.split(key(22), 20_000)
        for a, b in params:
            x = beta_draws(keys, a, b, jnp.dtype(dtype))
            assert x.dtype == jnp.dtype(dtype)
            x = np.asarray(x, np.float64)
            assert np.all((x >= 0) & (x <= 1)), (a, b)
            ref = stats.beta(a, b)
            p_tiny = ref.cdf(tiny)
            checks.binomial(int(np.sum(x <= tiny)), x.size, p_tiny, f"Beta({a}, {b}) below {tiny}")
            conditional = lambda t: (ref.cdf(t) - p_tiny) / (1 - p_tiny)  # noqa: E731
            checks.ks(x[x > tiny], conditional, f"Beta({a}, {b}) above {tiny}")
            checks.bounded_moments(x, ref, 0.0, 1.0, f"Beta({a}, {b})")
            probs = [p for p in QUANTILES if p > p_tiny + 0.01 and ref.ppf(p) < 1 - 1e-6]  # resolvable quantiles
            checks.below_quantiles(x, ref.ppf, probs, f"Beta({a}, {b})")


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


@pytest.mark.nightly  # by default: test_vmap_member_equals_single_call_bitwise (a vmapped batch against single calls)
def test_eager_call_equals_jitted_bitwise():
    alpha = posterior_like(20, 3, 2)
    keys = jax.random.split(jax.random.key(21), 2)
    batched = jax.jit(jax.vmap(sample_log_gamma, (0, None)))(keys, alpha)
    np.testing.assert_array_equal(batched[1], sample_log_gamma(keys[1], alpha))


@pytest.mark.nightly  # by default: test_vmap_member_equals_single_call_bitwise
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


@pytest.mark.statistical(p=1e-7)
def test_the_sampler_stream_is_not_the_key_own_stream():
    # Drawing does not repeat what the key gives jax.random: with u = uniform(key) and y = sample(key), u_i is
    # independent of F(y_i) (uniform, F the exact CDF of entry i), so the count of entries with both on the same side
    # of 1/2 is Binomial(n, 1/2). (The former |corr| < 0.1 with n = 288 failed about 9% of fresh keys.) 1 check:
    # false-failure probability <= 1e-7.
    alpha = posterior_like(40, 5, 1)  # 8000 entries
    k = key(18)
    y = np.asarray(sample_log_gamma(k, alpha), np.float64).ravel()
    u = np.asarray(jax.random.uniform(k, (alpha.size,)), np.float64)
    cdf = stats.loggamma(np.asarray(alpha, np.float64).ravel()).cdf(y)
    Checks().independent_signs(u, cdf, 0.5, 0.5, "uniform(key) against the draw's CDF")


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


@pytest.mark.statistical(p=5e-8)
def test_extreme_shapes_in_float64_are_finite():
    with jax.enable_x64(True):
        a = jnp.array([1e-300, 1e-30, 1e-5, 1e5, 1e30, 1e300], jnp.float64)
        y = np.asarray(sample_log_gamma(key(23), jnp.tile(a, 200), dtype=jnp.float64)).reshape(200, -1)
    assert np.all(np.isfinite(y))
    # ln G ~ ln(U) / a for tiny a: of order -1/a; ln G = ln a + O(1/sqrt(a)) for large a. False-failure bounds:
    # y < -1e290 (a = 1e-300) and y < -1e20 (a = 1e-30) fail only when U > 1 - 1e-10 (probability 1e-10 per draw,
    # 4e-8 over the 400 draws); for a >= 1e5, ln G - ln a is sqrt(1/a) N(0, 1) to O(1/a), so the band 7 / sqrt(1e5)
    # fails with probability 2 P(Z > 7) = 2.6e-12 per draw, 1.6e-9 over the 600 draws (the former 5 / sqrt(1e5):
    # 1.1e-4). False-failure probability <= 4e-8 + 1.6e-9 < 5e-8.
    assert np.all(y[:, 0] < -1e290) and np.all(y[:, 1] < -1e20)
    np.testing.assert_allclose(y[:, 3:], np.log(np.asarray(a[3:]))[None].repeat(200, 0), atol=7 / np.sqrt(1e5))


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="candidates"):
        sample_log_gamma(jax.random.key(0), jnp.ones(3), candidates=0)
    with pytest.raises(ValueError, match="buffers"):
        sample_log_gamma(jax.random.key(0), jnp.ones(300), buffers=(0, 1))
    assert sample_log_gamma(jax.random.key(0), jnp.ones((0, 3))).shape == (0, 3)
