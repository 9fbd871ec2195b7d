"""``fold_in``, ``split``, ``uniform`` and ``randint`` of ``jax.random``, bit for bit, with the hash written out so that
XLA fuses it; and :func:`uniform_index`, a cheaper uniform integer from ``jax.random.bits``' words.

A lockstep step calls ``jax.random`` a few times per member: the runner folds the step index into two member keys, the
environment splits its key and draws two uniforms, an agent draws a tie-breaking uniform. Each call hashes with
``threefry2x32_p``, which on CPU lowers to a rolled loop of its own, its state going through memory (on a GPU JAX
already emits it unrolled, so this module matters on CPU). Here the same Threefry-2x32 hash
(:func:`jaxmdp.sampling.threefry.threefry2x32`) is applied to the same counters, so the results are ``jax.random``'s
exactly (tests/test_fused_random.py), and XLA fuses the arithmetic with the step's own.

What ``jax.random`` computes, for a Threefry key ``(k0, k1)`` with ``jax_threefry_partitionable`` (the default since
jax 0.5):

* ``fold_in(key, d)`` is the hash of the counter ``(0, d)``: both output words form the new key;
* ``split(key, n)[i]`` is the hash of the counter ``(0, i)``;
* ``uniform(key, shape)`` hashes the counters ``(0, i)``, ``i`` the flat index of an entry. float32 takes the XOR of
  the two words, and float64 the 64-bit word ``(y0 << 32) | y1``. The top mantissa bits under the exponent of 1.0
  give a float in ``[1, 2)``, and 1 is subtracted from it (exact).
* ``randint(key, shape, lo, hi)`` (int32) splits the key in two and takes 32 bits per entry from each as above (the
  XOR of the words), ``b_hi`` and ``b_lo``; with ``n = hi - lo`` (1 where ``hi <= lo``) and ``m = (2^16 mod n)^2 mod
  n`` (``2^32 mod n``), the draw is ``lo + ((b_hi mod n) m + b_lo mod n) mod n`` in wrapping ``uint32`` arithmetic.

Raw ``uint32`` keys, keys of another implementation (``rbg``, ``unsafe_rbg``), the non-partitionable Threefry layout
and other float types go to ``jax.random`` itself, so every key gets ``jax.random``'s values.

Where the words of a hash feed many fusions, XLA may copy the hash into each one. Written out in episodic
Q-learning's action draw, which chains it to the runner's ``fold_in``, it makes the agent several times dearer, and
``jax.lax.optimization_barrier`` does not stop the copies. So the agents' draws keep ``jax.random``. These functions are
used where they pay: the runner's per-step keys, the environment's step and the random agent's action (faster episodic
runs of the random agent and faster environment steps on CPU; docs/performance.md, Environment step).
:func:`uniform_index` draws PSRL continuous's ``psi x S x A`` candidate states of a plan (docs/performance.md,
Continuous planning).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp.sampling.threefry import join_words, threefry2x32, unit_floats

__all__ = ["fold_in", "randint", "split", "uniform", "uniform_index"]


def _written_out(key: jax.Array) -> bool:
    """Whether ``key``'s ``jax.random`` values are the ones written out here: a typed Threefry key (not a raw
    ``uint32`` one), the partitionable layout."""
    return (jnp.issubdtype(key.dtype, jax.dtypes.prng_key) and jax.random.key_impl(key) == "threefry2x32"
            and bool(jax.config.jax_threefry_partitionable))


def _hash(key: jax.Array, counter: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The two words of the hash of ``(0, counter)`` under ``key``; ``counter`` ``uint32``, shaped ``key.shape + s``."""
    words = jax.random.key_data(key)
    k0 = words[..., 0].reshape(key.shape + (1,) * (counter.ndim - key.ndim))
    k1 = words[..., 1].reshape(k0.shape)
    return threefry2x32(k0, k1, jnp.zeros_like(counter), counter)


def _keys_from(key: jax.Array, y0: jax.Array, y1: jax.Array) -> jax.Array:
    """Keys of ``key``'s implementation whose two words are ``y0`` and ``y1``."""
    return jax.random.wrap_key_data(jnp.stack([y0, y1], axis=-1), impl=jax.random.key_impl(key))


def _check_single(key: jax.Array) -> None:
    """A written-out draw takes one key (``vmap`` over a batch): the error names the shape it got."""
    if key.shape:
        raise ValueError(f"key must be a single key (shape ()), got shape {key.shape}; vmap over a batch of keys")


def _broadcast_to(shape: tuple[int, ...], *arrays: jax.Array) -> bool:
    """Whether ``arrays`` broadcast to ``shape`` itself (not to a larger shape)."""
    try:
        return np.broadcast_shapes(tuple(shape), *(a.shape for a in arrays)) == tuple(shape)
    except ValueError:
        return False


def _words(key: jax.Array, shape: tuple[int, ...]) -> tuple[jax.Array, jax.Array]:
    """The two words of the hash of ``(0, i)`` for every entry ``i`` (flat index) of ``shape``; their XOR is
    ``jax.random.bits(key, shape, uint32)``."""
    return _hash(key, jnp.arange(int(np.prod(shape, dtype=np.int64)), dtype=jnp.uint32).reshape(shape))


def fold_in(key: jax.Array, data: jax.Array | int) -> jax.Array:
    """``jax.random.fold_in(key, data)``: the key hashed with the counter ``(0, data)``, for typed ``key`` of any
    shape and an integer ``data`` that broadcasts to it (converted to ``uint32`` as ``jax.random`` converts it)."""
    if not _written_out(key):
        if not key.shape or not jnp.issubdtype(key.dtype, jax.dtypes.prng_key):  # one key (a raw key is one)
            return jax.random.fold_in(key, data)
        data = jnp.broadcast_to(jnp.asarray(data, dtype=jnp.uint32), key.shape)
        return jax.vmap(jax.random.fold_in)(key.reshape(-1), data.reshape(-1)).reshape(key.shape)
    return _keys_from(key, *_hash(key, jnp.broadcast_to(jnp.asarray(data, dtype=jnp.uint32), key.shape)))


def split(key: jax.Array, num: int | tuple[int, ...] = 2) -> jax.Array:
    """``jax.random.split(key, num)`` of a single typed ``key``: ``num`` keys, key ``i`` the hash of ``(0, i)`` (a
    shape ``num`` goes to ``jax.random.split``)."""
    if not _written_out(key) or not isinstance(num, int):
        return jax.random.split(key, num)
    _check_single(key)
    return _keys_from(key, *_hash(key, jnp.arange(num, dtype=jnp.uint32)))


def uniform(key: jax.Array, shape: tuple[int, ...] = (), dtype: Any = None) -> jax.Array:
    """``jax.random.uniform(key, shape, dtype)`` on ``[0, 1)`` for a single ``key``: entry ``i`` (flat index) from
    the hash of ``(0, i)``, its top mantissa bits under the exponent of 1.0, minus 1. ``dtype`` None: JAX's default
    float type, as ``jax.random.uniform``'s."""
    dtype = jax.dtypes.canonicalize_dtype(float if dtype is None else dtype)
    size = int(np.prod(shape, dtype=np.int64))
    if not _written_out(key) or dtype not in (jnp.float32, jnp.float64) or size >= 2**32:
        return jax.random.uniform(key, shape, dtype)
    _check_single(key)
    y0, y1 = _words(key, shape)
    return unit_floats(y0 ^ y1 if dtype == jnp.float32 else join_words(y0, y1), dtype)


def randint(key: jax.Array, shape: tuple[int, ...], minval: Any, maxval: Any, dtype: Any = jnp.int32) -> jax.Array:
    """``jax.random.randint(key, shape, minval, maxval, dtype)`` for a single ``key``: ``int32`` draws in ``[minval,
    maxval)`` from 64 random bits each (module docstring; ``jax.random``'s bias for spans that are not powers of two
    included). ``minval``/``maxval`` are ``int32`` scalars or arrays that broadcast to ``shape``; other integer types
    and keys go to ``jax.random``."""
    dtype = jax.dtypes.canonicalize_dtype(dtype)
    lo, hi = jnp.asarray(minval), jnp.asarray(maxval)
    size = int(np.prod(shape, dtype=np.int64))
    if (not _written_out(key) or dtype != jnp.int32 or lo.dtype != jnp.int32 or hi.dtype != jnp.int32
            or size >= 2**32):
        return jax.random.randint(key, shape, minval, maxval, dtype)
    _check_single(key)
    if not _broadcast_to(shape, lo, hi):
        raise ValueError(f"minval and maxval must broadcast to shape {tuple(shape)}; "
                         f"got shapes {lo.shape} and {hi.shape}")
    k_hi, k_lo = split(key, 2)
    b_hi, b_lo = (jnp.bitwise_xor(*_words(k, tuple(shape))) for k in (k_hi, k_lo))
    lo, hi = jax.lax.broadcast_to_rank(lo, len(shape)), jax.lax.broadcast_to_rank(hi, len(shape))
    span = jnp.where(hi <= lo, jnp.uint32(1), (hi - lo).astype(jnp.uint32))
    multiplier = jnp.uint32(2**16) % span
    multiplier = multiplier * multiplier % span
    offset = ((b_hi % span) * multiplier + b_lo % span) % span
    return lo + offset.astype(jnp.int32)


def _mul_hi(a: jax.Array, b: jax.Array) -> jax.Array:
    """``floor(a b / 2^32)`` of ``uint32`` arrays, exactly, from 16-bit halves (products below ``2^32``): XLA CPU
    vectorises these ``uint32`` multiplies, where a ``uint64`` product or an integer remainder runs scalar."""
    half, low = np.uint32(16), np.uint32(0xFFFF)
    a_hi, a_lo, b_hi, b_lo = a >> half, a & low, b >> half, b & low
    middle = a_hi * b_lo + ((a_lo * b_lo) >> half)  # < 2^32
    middle_2 = a_lo * b_hi + (middle & low)  # < 2^32
    return a_hi * b_hi + (middle >> half) + (middle_2 >> half)


def uniform_index(key: jax.Array, shape: tuple[int, ...], n: Any) -> jax.Array:
    """Uniform ``int32`` draws on ``{0, ..., n - 1}`` for a single ``key``: ``floor(n b / 2^32)`` (Lemire's
    multiply-shift, without rejection) of the word ``b = jax.random.bits(key, shape, uint32)``, for ``int32`` ``n``
    (a scalar or an array that broadcasts to ``shape``; ``n <= 0`` draws 0).

    Each value takes ``floor(2^32 / n)`` or one more of the ``2^32`` words, so its probability is within ``2^-32`` of
    ``1 / n``. One hash and a few multiplies an entry, against :func:`randint`'s two hashes and three remainders
    (``jax.random.randint``'s bits; an integer remainder by a traced ``n`` does not vectorise on a CPU): about 12x on
    a CPU (docs/performance.md, Continuous planning). Not ``jax.random.randint``'s values.
    """
    n = jnp.asarray(n)
    if n.dtype != jnp.int32:
        raise ValueError(f"n must be int32 (a scalar or an array broadcasting to shape), got {n.dtype}")
    if not _broadcast_to(shape, n):
        raise ValueError(f"n must broadcast to shape {tuple(shape)}; got shape {n.shape}")
    size = int(np.prod(shape, dtype=np.int64))
    if not _written_out(key) or size >= 2**32:
        bits = jax.random.bits(key, shape, jnp.uint32)
    else:
        _check_single(key)
        bits = jnp.bitwise_xor(*_words(key, tuple(shape)))
    span = jnp.maximum(jax.lax.broadcast_to_rank(n, len(shape)), 0).astype(jnp.uint32)
    return _mul_hi(bits, span).astype(jnp.int32)
