"""Stream compaction with a static size: the indices of the first ``size`` true entries of a flag array.

``jnp.nonzero(flags, size=...)`` does this with a cumulative sum and a scatter over all ``n`` entries; here the flags
are packed 32 to a ``uint32`` word first, so the prefix sum and the scatter run over ``n / 32`` words and the rest
over the ``size`` output slots: about ten times cheaper when ``size`` is a small fraction of ``n`` (the rejected
entries of a rejection sampler). Pure ``jnp``; ``vmap`` compacts every member on its own.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["compact", "compact_with_count"]

_U32 = jnp.uint32
_BIT = np.left_shift(np.uint32(1), np.arange(32, dtype=np.uint32))  # bit b of a word holds flag 32 * word + b


def compact(flags: jax.Array, size: int) -> tuple[jax.Array, jax.Array]:
    """``(index, valid)``: ``index[s]`` is the position of the ``s``-th true entry of the flat ``bool[n]`` array
    ``flags`` (increasing), for ``s`` below ``min(size, count)``, and ``valid[s]`` says so.

    Slots past the count hold ``n + s``: distinct and out of range, so a ``gather(mode="clip")`` reads something
    harmless and a ``scatter(mode="drop")`` ignores them. True entries past the first ``size`` are left out.
    """
    index, valid, _ = compact_with_count(flags, size)
    return index, valid


def compact_with_count(flags: jax.Array, size: int) -> tuple[jax.Array, jax.Array, jax.Array]:
    """:func:`compact` and the number of true entries (``int32``), which exceeds ``size`` exactly when some were
    left out; it comes from the packed words' counts, without another pass over ``flags``."""
    n = flags.shape[0]
    if n >= 2**31 - 64 - size:
        raise ValueError(f"compact: flags has {n} entries; at most 2**31 - 64 - size are supported")
    n_words = -(-n // 32)
    packed = jnp.pad(flags, (0, 32 * n_words - n)).reshape(n_words, 32)
    words = jnp.sum(jnp.where(packed, _BIT, _U32(0)), axis=1, dtype=_U32)  # distinct bits: the sum is the "or"
    counts = jax.lax.population_count(words).astype(jnp.int32)
    before = jnp.cumsum(counts) - counts  # true entries in earlier words
    total = before[-1] + counts[-1]
    # Slot -> word: each word with a true entry marks the slot of its first one; a running maximum fills the gaps.
    word_id = jnp.arange(n_words, dtype=jnp.int32)
    starts = jnp.zeros((size,), jnp.int32).at[jnp.where(counts > 0, before, size)].max(word_id, mode="drop")
    word = jax.lax.cummax(starts)
    slot = jnp.arange(size, dtype=jnp.int32)
    # Bit of the k-th set bit of the word by bisection: skip the low half while it holds k or fewer set bits.
    k = slot - before[word]
    bits = words[word]
    position = jnp.zeros((size,), jnp.int32)
    for width in (16, 8, 4, 2, 1):
        low = jax.lax.population_count(bits & _U32((1 << width) - 1)).astype(jnp.int32)
        skip = k >= low
        bits = jnp.where(skip, bits >> _U32(width), bits)
        k = jnp.where(skip, k - low, k)
        position = position + jnp.where(skip, width, 0)
    valid = slot < total
    return jnp.where(valid, 32 * word + position, n + slot), valid, total
