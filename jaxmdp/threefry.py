"""Threefry-2x32 (Salmon et al., 2011) on explicit counters, written as plain ``jnp`` integer arithmetic.

``jax.random`` evaluates the same hash, but on CPU it lowers it as a rolled loop over whole arrays (five passes
through memory per call), and a 32-bit draw spends a whole hash (its two words XORed into one). Here the 20 rounds
are unrolled, so XLA fuses the hash with whatever consumes its words: a draw becomes compute-bound (about 2 ns per
hash on one core, against ~11 ns per 32-bit word from ``jax.random.bits``) and both words are used. The output is bit-for-bit ``jax.random``'s Threefry-2x32 (``tests/test_gamma_sampler.py`` checks it against
``jax.extend.random.threefry_2x32``).

Counters are two ``uint32`` words ``(hi, lo)``: callers use ``hi`` for a trial number and ``lo`` for an entry index,
so every (trial, entry) pair has its own pair of random words, whatever the array shape or batch around it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["threefry2x32", "key_words", "unit_float"]

_U32 = jnp.uint32
# Threefry-2x32 rotation constants (two alternating groups of four rounds) and the key-schedule parity constant.
_ROTATIONS = ((13, 15, 26, 6), (17, 29, 16, 24))
_PARITY = 0x1BD11BDA


def threefry2x32(k0: jax.Array, k1: jax.Array, hi: jax.Array, lo: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Threefry-2x32 with 20 rounds of the key ``(k0, k1)`` applied to the counter ``(hi, lo)`` (``uint32``, any
    broadcastable shapes). Returns the two output words."""
    ks = (k0, k1, k0 ^ k1 ^ _U32(_PARITY))
    x0, x1 = hi + ks[0], lo + ks[1]
    for block in range(5):  # five blocks of four rounds, a key injection after each
        for r in _ROTATIONS[block % 2]:
            x0 = x0 + x1
            x1 = ((x1 << _U32(r)) | (x1 >> _U32(32 - r))) ^ x0
        x0 = x0 + ks[(block + 1) % 3]
        x1 = x1 + ks[(block + 2) % 3] + _U32(block + 1)
    return x0, x1


def key_words(key: jax.Array, tag: int) -> tuple[jax.Array, jax.Array]:
    """A Threefry key ``(k0, k1)`` for the stream ``tag`` of ``key``: the words of ``jax.random.fold_in(key, tag)``.

    For Threefry keys (typed, or raw ``uint32[2]`` under the default implementation) this is the fold-in itself,
    ``threefry2x32(key, (0, tag))``, evaluated here (``jax.random``'s rolled loop is slow for a batch of keys);
    other implementations draw two words from ``fold_in(key, tag)``. Nothing else drawn from ``key`` overlaps it.
    """
    if jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        threefry = str(jax.random.key_impl(key)) == "threefry2x32"
    else:  # a raw key array
        threefry = key.shape[-1:] == (2,) and str(jax.config.jax_default_prng_impl) == "threefry2x32"
    if threefry:
        data = jax.random.key_data(key)
        return threefry2x32(data[..., 0], data[..., 1], _U32(0), _U32(tag))
    words = jax.random.bits(jax.random.fold_in(key, tag), (2,), jnp.uint32)
    return words[0], words[1]


def unit_float(words: tuple[jax.Array, ...], dtype) -> jax.Array:
    """A uniform on ``[0, 1)`` from random ``uint32`` words, as ``jax.random.uniform`` makes it: the top mantissa
    bits under exponent 0 minus one. ``float32`` takes one word (23 bits, grid ``2^-23``); ``float64`` two (52 bits).
    """
    if jnp.dtype(dtype) == jnp.float64:
        bits = (words[0].astype(jnp.uint64) << jnp.uint64(32)) | words[1].astype(jnp.uint64)
        one = jax.lax.bitcast_convert_type((bits >> jnp.uint64(12)) | jnp.uint64(0x3FF0000000000000), jnp.float64)
        return one - 1.0
    one = jax.lax.bitcast_convert_type((words[0] >> _U32(9)) | _U32(0x3F800000), jnp.float32)
    return one - 1.0
