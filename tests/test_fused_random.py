"""jaxmdp.sampling.fused_random: jax.random's fold_in, split, uniform and randint, bit for bit, for all keys."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmdp.sampling import fused_random as fr

SEEDS = [0, 1, 12345, 2**31 + 7]


def words(keys: jax.Array) -> np.ndarray:
    return np.asarray(jax.random.key_data(keys))


def same_bits(a: jax.Array, b: jax.Array) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("seed", SEEDS)
def test_fold_in_and_split_equal_jax_random(seed):
    key = jax.random.key(seed)
    for data in [0, 1, 7, 2**31, 2**32 - 1]:
        assert same_bits(words(fr.fold_in(key, data)), words(jax.random.fold_in(key, data)))
    for num in [1, 2, 3, 5, (2, 3)]:
        assert same_bits(words(fr.split(key, num)), words(jax.random.split(key, num)))
    jitted = jax.jit(lambda k, d: fr.fold_in(k, d))(key, jnp.uint32(99))
    assert same_bits(words(jitted), words(jax.random.fold_in(key, 99)))


def test_fold_in_of_a_batch_of_keys_equals_the_vmapped_jax_random():
    keys = jax.random.split(jax.random.key(3), 6)
    expected = jax.vmap(jax.random.fold_in, in_axes=(0, None))(keys, jnp.uint32(17))
    assert same_bits(words(fr.fold_in(keys, jnp.uint32(17))), words(expected))  # one datum for every key
    data = jnp.arange(6, dtype=jnp.int32)
    expected = jax.vmap(jax.random.fold_in)(keys, data)
    assert same_bits(words(jax.jit(fr.fold_in)(keys, data)), words(expected))  # a datum per key
    assert same_bits(words(jax.vmap(fr.fold_in)(keys, data)), words(expected))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("shape", [(), (1,), (2,), (7,), (3, 4)])
def test_uniform_equals_jax_random(seed, shape):
    key = jax.random.key(seed)
    expected = jax.random.uniform(key, shape, jnp.float32)
    assert same_bits(fr.uniform(key, shape, jnp.float32), expected)
    assert same_bits(jax.jit(lambda k: fr.uniform(k, shape, jnp.float32))(key), expected)
    assert same_bits(fr.uniform(key, shape), jax.random.uniform(key, shape))  # the default float type
    keys = jax.random.split(key, 4)
    expected = jax.vmap(lambda k: jax.random.uniform(k, shape))(keys)
    assert same_bits(jax.vmap(lambda k: fr.uniform(k, shape))(keys), expected)


@pytest.mark.nightly  # float64; by default: the float32 uniform test
def test_uniform_in_float64_equals_jax_random():
    with jax.enable_x64(True):
        key = jax.random.key(5)
        for shape in [(), (2,), (3, 5)]:
            value = fr.uniform(key, shape, jnp.float64)
            assert value.dtype == jnp.float64 and same_bits(value, jax.random.uniform(key, shape, jnp.float64))
        assert same_bits(fr.uniform(key), jax.random.uniform(key))  # the default float type is float64 here


def test_other_keys_and_types_go_to_jax_random():
    rbg = jax.random.key(0, impl="rbg")
    assert same_bits(words(fr.fold_in(rbg, 3)), words(jax.random.fold_in(rbg, 3)))
    assert same_bits(words(fr.split(rbg, 3)), words(jax.random.split(rbg, 3)))
    assert same_bits(fr.uniform(rbg, (3,)), jax.random.uniform(rbg, (3,)))
    batch = jax.random.split(rbg, 4)
    expected = jax.vmap(jax.random.fold_in, in_axes=(0, None))(batch, 2)
    assert same_bits(words(fr.fold_in(batch, 2)), words(expected))
    raw = jax.random.PRNGKey(4)  # a raw uint32 key
    assert same_bits(fr.fold_in(raw, 3), jax.random.fold_in(raw, 3))
    assert same_bits(fr.split(raw), jax.random.split(raw))
    assert same_bits(fr.uniform(raw, (2,)), jax.random.uniform(raw, (2,)))
    key = jax.random.key(0)
    assert same_bits(fr.uniform(key, (2,), jnp.bfloat16), jax.random.uniform(key, (2,), jnp.bfloat16))
    with jax.threefry_partitionable(False):
        assert same_bits(words(fr.split(key, 3)), words(jax.random.split(key, 3)))
        assert same_bits(fr.uniform(key, (5,)), jax.random.uniform(key, (5,)))


# Spans: 1, powers of two, odd, just past 2^16 (where the multiplier's square wraps uint32), int32's whole range,
# an empty range (hi <= lo: always lo) and negative bounds.
RANGES = [(0, 1), (0, 2), (0, 3), (0, 948), (-5, 7), (0, 2**16), (0, 2**16 + 1), (3, 2**31 - 1),
          (-(2**31), 2**31 - 1), (4, 4), (9, 2)]


@pytest.mark.parametrize("seed", SEEDS)
def test_randint_equals_jax_random(seed):
    key = jax.random.key(seed)
    draw = jax.jit(fr.randint, static_argnums=1)
    for lo, hi in RANGES:
        for shape in [(), (5,), (3, 4)]:
            expected = jax.random.randint(key, shape, lo, hi)
            assert same_bits(fr.randint(key, shape, lo, hi), expected), (lo, hi, shape)
            assert same_bits(draw(key, shape, jnp.int32(lo), jnp.int32(hi)), expected), (lo, hi, shape)


@pytest.mark.nightly  # by default: test_randint_equals_jax_random
def test_randint_with_array_bounds_and_a_batch_of_keys_equals_jax_random():
    key = jax.random.key(11)
    lo, hi = jnp.array([0, -3, 7], jnp.int32), jnp.array([[5], [1000]], jnp.int32)  # broadcast to (2, 3)
    assert same_bits(fr.randint(key, (2, 3), lo, hi), jax.random.randint(key, (2, 3), lo, hi))
    keys, n = jax.random.split(key, 4), jnp.array([1, 2, 948, 2**20], jnp.int32)
    expected = jax.vmap(lambda k, m: jax.random.randint(k, (6, 2), 0, m))(keys, n)
    assert same_bits(jax.vmap(lambda k, m: fr.randint(k, (6, 2), 0, m))(keys, n), expected)


def test_randint_of_other_keys_and_types_goes_to_jax_random():
    rbg, raw, key = jax.random.key(0, impl="rbg"), jax.random.PRNGKey(4), jax.random.key(2)
    assert same_bits(fr.randint(rbg, (4,), 0, 9), jax.random.randint(rbg, (4,), 0, 9))
    assert same_bits(fr.randint(raw, (4,), 0, 9), jax.random.randint(raw, (4,), 0, 9))
    assert same_bits(fr.randint(key, (4,), 0, 9, jnp.uint8), jax.random.randint(key, (4,), 0, 9, jnp.uint8))
    with jax.threefry_partitionable(False):
        assert same_bits(fr.randint(key, (5,), 0, 9), jax.random.randint(key, (5,), 0, 9))


def test_split_and_uniform_want_one_key():
    keys = jax.random.split(jax.random.key(0), 2)
    with pytest.raises(ValueError, match="single key"):
        fr.split(keys)
    with pytest.raises(ValueError, match="single key"):
        fr.uniform(keys, (2,))
    with pytest.raises(ValueError, match="single key"):
        fr.randint(keys, (2,), 0, 3)
    with pytest.raises(ValueError, match=r"must broadcast to shape \(2,\); got shapes \(3,\) and \(\)"):
        fr.randint(keys[0], (2,), jnp.zeros(3, jnp.int32), 3)


# uniform_index: floor(n b / 2^32) of jax.random.bits' words, for spans up to int32's largest and the empty one.
SPANS = [1, 2, 3, 7, 948, 2**16, 2**16 + 1, 123_456_789, 2**31 - 1, 0, -4]


def expected_index(key: jax.Array, shape: tuple[int, ...], n) -> np.ndarray:
    """Lemire's multiply-shift in numpy's exact uint64 arithmetic (a product of two words is below 2^64)."""
    bits = np.asarray(jax.random.bits(key, shape, jnp.uint32)).astype(np.uint64)
    span = np.maximum(np.asarray(n, np.int64), 0).astype(np.uint64)
    return ((bits * span) >> np.uint64(32)).astype(np.int32)


@pytest.mark.parametrize("seed", SEEDS)
def test_uniform_index_is_the_multiply_shift_of_jax_random_bits(seed):
    key = jax.random.key(seed)
    draw = jax.jit(fr.uniform_index, static_argnums=1)
    for n in SPANS:
        for shape in [(), (5,), (3, 4), (60, 7, 3)]:
            expected = expected_index(key, shape, n)
            got = fr.uniform_index(key, shape, jnp.int32(n))
            assert same_bits(got, expected), (n, shape)
            assert same_bits(draw(key, shape, jnp.int32(n)), expected), (n, shape)  # a traced span
            got = np.asarray(got)
            assert got.min() >= 0 and got.max() <= max(n - 1, 0), (n, shape)


def test_uniform_index_with_array_spans_batches_of_keys_and_other_keys():
    key = jax.random.key(21)
    spans = jnp.array([[1], [948], [2**31 - 1]], jnp.int32)  # broadcast to (3, 4)
    assert same_bits(fr.uniform_index(key, (3, 4), spans), expected_index(key, (3, 4), np.asarray(spans)))
    keys, n = jax.random.split(key, 4), jnp.array([1, 2, 784, 2**20], jnp.int32)
    got = jax.vmap(lambda k, m: fr.uniform_index(k, (6, 2), m))(keys, n)
    for i in range(4):
        assert same_bits(got[i], expected_index(keys[i], (6, 2), int(n[i])))
    for other in (jax.random.key(0, impl="rbg"), jax.random.PRNGKey(4)):  # jax.random.bits' words of any key
        assert same_bits(fr.uniform_index(other, (9,), jnp.int32(948)), expected_index(other, (9,), 948))
    with jax.threefry_partitionable(False):
        assert same_bits(fr.uniform_index(key, (9,), jnp.int32(5)), expected_index(key, (9,), 5))


def test_mul_hi_is_exact_on_uint32():
    edges = np.array([0, 1, 2, 0xFFFF, 0x10000, 0x10001, 2**31 - 1, 2**31, 2**32 - 2, 2**32 - 1], np.uint64)
    rng = np.random.default_rng(7)
    a = np.concatenate([np.repeat(edges, edges.size), rng.integers(0, 2**32, 4096, dtype=np.uint64)])
    b = np.concatenate([np.tile(edges, edges.size), rng.integers(0, 2**32, 4096, dtype=np.uint64)])
    expected = np.array([(int(x) * int(y)) >> 32 for x, y in zip(a, b)], np.uint64)
    got = fr._mul_hi(jnp.asarray(a.astype(np.uint32)), jnp.asarray(b.astype(np.uint32)))
    np.testing.assert_array_equal(np.asarray(got).astype(np.uint64), expected)


def test_uniform_index_refuses_bad_spans_and_batches_of_keys():
    key = jax.random.key(0)
    with pytest.raises(ValueError, match="n must be int32"):
        fr.uniform_index(key, (3,), jnp.int64(5) if jax.config.jax_enable_x64 else np.uint32(5))
    with pytest.raises(ValueError, match=r"n must broadcast to shape \(3,\)"):
        fr.uniform_index(key, (3,), jnp.ones((4,), jnp.int32))
    with pytest.raises(ValueError, match="single key"):
        fr.uniform_index(jax.random.split(key, 2), (3,), jnp.int32(5))
