"""The Threefry-2x32 hash written out round by round, so that XLA fuses it with the arithmetic that uses its words.

``jax.random`` hashes with the same function (``jax.extend.random.threefry2x32_p``), but on CPU its lowering is a
rolled loop of five iterations (four rounds each): every ``jax.random`` call in a ``vmap``-ed step is a loop of its
own whose state goes through memory, which costs the same whether it hashes one counter per member or several
(docs/performance.md, Sampling). Unrolled, a hash is about a hundred integer operations inside the fusion of its
consumers. The values are those of ``threefry2x32_p`` bit for bit (tests/test_beta_rewards.py). Used by the
step's reward sampler :mod:`jaxmdp.sampling.beta_shared`, the Gamma sampler's trials
(:mod:`jaxmdp.sampling.beta_sampling`) and :mod:`jaxmdp.sampling.fused_random`, which also share the words' conversion
to floats (:func:`unit_floats`, :func:`join_words`).

Threefry-2x32 with 20 rounds: Salmon, Moraes, Dror and Shaw, "Parallel random numbers: as easy as 1, 2, 3" (SC 2011).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["threefry2x32", "join_words", "unit_floats"]

_ROTATIONS = ((13, 15, 26, 6), (17, 29, 16, 24))  # rotation constants of the even and odd groups of four rounds
_PARITY = np.uint32(0x1BD11BDA)  # key-schedule constant of Threefry-2x32


def threefry2x32(k0: jax.Array, k1: jax.Array, x0: jax.Array, x1: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Threefry-2x32 (20 rounds) of the counter ``(x0, x1)`` under the key ``(k0, k1)``, elementwise on ``uint32``
    arrays that broadcast together: the two output words, equal to ``jax.extend.random.threefry2x32_p``'s."""
    ks = (k0, k1, k0 ^ k1 ^ _PARITY)
    x0, x1 = x0 + ks[0], x1 + ks[1]
    for group in range(5):
        for rot in _ROTATIONS[group % 2]:
            x0 = x0 + x1
            x1 = (x1 << np.uint32(rot)) | (x1 >> np.uint32(32 - rot))
            x1 = x0 ^ x1
        x0 = x0 + ks[(group + 1) % 3]
        x1 = x1 + ks[(group + 2) % 3] + np.uint32(group + 1)
    return x0, x1


def join_words(hi: jax.Array, lo: jax.Array) -> jax.Array:
    """The ``uint64`` words ``(hi << 32) | lo`` of two ``uint32`` words (how ``jax.random`` forms 64-bit words)."""
    return (hi.astype(jnp.uint64) << np.uint64(32)) | lo.astype(jnp.uint64)


def unit_floats(bits: jax.Array, dtype: jax.typing.DTypeLike) -> jax.Array:
    """Floats on ``[0, 1)`` from unsigned words as ``jax.random.uniform`` forms them: the words' top mantissa bits under
    the exponent of 1.0 give a float in ``[1, 2)``, and 1 is subtracted (exactly). ``bits``: ``uint32`` words for
    float32, ``uint64`` for float64."""
    nbits = np.iinfo(bits.dtype).bits
    one = np.array(1.0, dtype).view(bits.dtype)
    floats = jax.lax.bitcast_convert_type((bits >> np.array(nbits - np.finfo(dtype).nmant, bits.dtype)) | one, dtype)
    return floats - np.array(1.0, dtype)
