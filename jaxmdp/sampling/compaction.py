"""Stream compaction with a static size: the indices of the first ``size`` true entries of a flag array.

``jnp.nonzero(flags, size=...)`` does this with a cumulative sum and a scatter over all ``n`` entries; here the flags
are packed 32 to a ``uint32`` word first, so the prefix sum and the scatter run over ``n / 32`` words and the rest
over the ``size`` output slots: about ten times cheaper when ``size`` is a small fraction of ``n`` (the rejected
entries of a rejection sampler). Pure ``jnp``; ``vmap`` compacts every member on its own.

Each output slot finds its word by counting the words whose first rank is at most the slot (a scatter-add over the
words, then a prefix sum over the slots). The count is used instead of a running maximum over the slots
(``lax.cummax``), which gives the same words, because XLA lowers the running maximum on a CPU as a scan of ``log size``
levels that costs several times the cumulative sum; the flags are packed by shifts instead of a select per flag for the
same reason (docs/performance.md, Sampling).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["compact", "compact_with_count"]

_U32 = jnp.uint32
_SHIFT = np.arange(32, dtype=np.uint32)  # bit b of a word holds flag 32 * word + b


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
    packed = jnp.pad(flags, (0, 32 * n_words - n)).reshape(n_words, 32).astype(_U32)
    words = jnp.sum(packed << _SHIFT, axis=1, dtype=_U32)  # distinct bits: the sum is the "or"
    counts = jax.lax.population_count(words).astype(jnp.int32)
    through = jnp.cumsum(counts)  # true entries up to each word
    before = through - counts  # in earlier words: the rank of the word's first true entry
    total = through[-1]
    # Slot -> word: the last word whose first rank is at most the slot, which holds the slot's entry (the next word's
    # first rank is past the slot). Its index is the number of such words, less one: every word counts one at its
    # first rank (ranks past the slots dropped), and a prefix sum over the slots adds them up.
    first_ranks = jnp.zeros((size,), jnp.int32).at[before].add(1, mode="drop")
    word = jnp.cumsum(first_ranks) - 1
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
