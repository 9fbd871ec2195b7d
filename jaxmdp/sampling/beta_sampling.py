"""Exact Gamma and Beta variates that vectorise well: rejection sampling whose rare rejections are compacted.

The Gamma sampler of the agents' Dirichlet and Normal-Gamma posterior draws (:mod:`agents.posteriors`). Its trial
(:func:`trial_log_gamma`, :func:`shape_terms`) is also that of the environment's reward sampler
:mod:`jaxmdp.sampling.beta_shared`, which the step uses instead of :func:`sample_beta` because it makes the step several
times faster (docs/performance.md, Environment step).

**Method.** Marsaglia & Tsang (2000) for the shape ``a' >= 1``: ``d = a' - 1/3``, ``c = 1 / sqrt(9 d)``; a trial
draws ``x ~ N(0, 1)`` and ``w ~ U(0, 1]``, sets ``v = (1 + c x)^3`` and accepts ``d v`` when ``v > 0`` and
``w < 1 - 0.0331 x^4`` (squeeze) or ``ln w < ln t(x) = x^2 / 2 + d (1 - v + ln v)``. A trial is accepted with
probability above 0.95 (worst at ``a' = 1``: 0.9517). Shapes ``a < 1`` are boosted, ``Gamma(a) = Gamma(a + 1)
U^(1/a)``, in log space so that tiny shapes (Colosseum uses ``a = 0.01``) do not underflow: ``ln G = ln(d v) +
ln(U) / a``. The boost's uniform is the accepted trial's own: given ``x`` and acceptance, ``w`` is uniform on
``(0, t(x)]`` (the squeeze region lies inside ``w < t(x)``), so ``U = w / t(x)`` is uniform on ``(0, 1]`` and
independent of the accepted value: ``ln U = ln w - ln t(x)``. This is exact, not an approximation; it saves a
third random word per entry. Its rounding is that of ``ln t(x)`` in float32: ~1e-7 absolute on average over the
accepted trials (the size of the rounding of ``ln U`` from a separate uniform), up to ~1e-5 in trials with
``t(x) > 1e-3``; divided by ``a`` as any error of ``ln U``. (A separate uniform costs noticeably more time; the
algebraically equal ``ln t = 3 d (log1p(c x) - c x + (c x)^2 / 2 - (c x)^3 / 3)`` halves the rounding but costs more
too; docs/performance.md, Sampling.)

**Random numbers.** Keys folded from ``fold_in(key, 2^31 - 1)`` (nothing else drawn from ``key`` overlaps it). A round's
trials are drawn at once from the round's key: two key words from ``jax.random.bits``, then one Threefry-2x32 hash per
entry of the counter ``(entry, 0)`` (a second, ``(entry, 1)``, in float64), whose two words make the trial's ``x`` and
``w`` (:func:`trial_deviates`). The hash is :func:`jaxmdp.sampling.threefry.threefry2x32` written out, which XLA fuses
with the trial's arithmetic; ``jax.random`` evaluates each 32-bit word's hash in a rolled loop over memory, which costs
most of a Dirichlet draw on CPU (docs/performance.md, Sampling). The whole-array round uses tag 0 of the sampler's key;
pass ``p`` over the rejected entries uses the key ``fold_in(., p + 1)``, its first buffer that key's tag 0 and its
second buffer's rounds tags 1, 2, ...; small arrays run rounds on tags 0, 1, 2, ... . A buffer slot draws its own
deviates: which entry sits in a slot was decided by earlier trials only, so the slot's fresh draws are independent of
it. ``x = sqrt(2) erf_inv(v)`` with ``v`` uniform on the float grid of ``(-1, 1)``: the deviates stop at about 5.2-5.4,
which truncates the normal's tails at ``P(|x| > 5.2) ~ 2e-7``, as ``jax.random.normal`` (and ``jax.random.gamma``) do.

**Rounds.** A large array (``n`` entries) runs one round over every entry, which accepts > 95% of them. The rejected
entries are compacted (:func:`jaxmdp.sampling.compaction.compact`) into a buffer of ``m1 = n // 16 + 64`` slots that
runs one more trial each; the entries it rejects go to a buffer of ``m2 = m1 // 16 + 64`` slots that runs rounds of four
trials until every one is accepted; the results are scattered back. At most 4.83% of the entries are rejected per trial,
so a buffer overflows with probability below ``1e-16`` whatever ``n`` (binomial tails, worst shape); if one does (the
compactions' counts say so), the whole pass (compaction, both buffers) repeats on the entries still rejected, with a
fresh key, until no buffer overflows. The passes loop on the overflow, not on "some entry is still rejected", because
the latter reads every member's whole array twice under ``vmap`` for the same values (docs/performance.md, Sampling).
Whole-array rounds until every entry is accepted would cost, for ``n ~ 10^6``, about five rounds of three random words
per entry, where this sampler runs one round (two words per entry) and then trials for the ~5% it rejected.
``jax.random.gamma`` runs a ``while_loop`` per entry that splits its key at every trial. Small arrays (below 1024
entries, e.g. the two Gammas of one Beta) run rounds of ``candidates`` trials over the whole array.

Every entry gets the first accepted trial of a sequence of trials on fresh random numbers, the sequence chosen by
rejections alone: exactly rejection sampling, the entries independent. The loops end with probability one (every
trial is accepted with probability > 0.95).

**Same key, same value; batches.** The values are a function of the key, the shapes and the buffer sizes, and a
member of a ``vmap``-ed batch gets bit for bit the value it would get alone, as does an eager call that of a jitted
one (tested). Two details keep it so: both functions are jitted as a whole (dispatched op by op, ``1 + c x`` is not
contracted into a fused multiply-add as it is inside a fused loop), and no product with a constant factor is
multiplied by a per-entry shape term: ``(sqrt(2) e) c``, with ``c`` broadcast from an unbatched ``a``, was
reassociated by XLA into ``e (sqrt(2) c)``, which changed the last bits of ``v``; ``sqrt(2) c`` is therefore one
per-entry constant. (A shape array that is a compile-time constant may give last-bit differences from the same
array passed as an argument: XLA folds its shape terms on the host.)

**Bad input.** ``a = 0`` gives ``ln G = -inf`` (``Gamma(0)`` is the point mass at 0), ``a = +inf`` gives ``+inf``;
a negative or NaN shape gives NaN. Never a hang: such entries are drawn with shape 1 and replaced.

The values are exact draws (up to floating-point rounding, as for ``jax.random``); the random stream differs from
``jax.random.gamma``'s and from this module's earlier versions.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp.sampling.compaction import compact_with_count
from jaxmdp.sampling.threefry import join_words, threefry2x32, unit_floats

__all__ = ["sample_log_gamma", "sample_beta", "buffer_sizes", "shape_terms", "trial_log_gamma", "trial_deviates",
           "deviates_from_words", "DEFAULT_CANDIDATES"]

#: Trials per round for arrays too small to compact: with acceptance > 0.95 a round fails with probability < 7e-6.
DEFAULT_CANDIDATES = 4

_STREAM = 2**31 - 1  # fold_in tag of the sampler's key
_FINE_CANDIDATES = 4  # trials per slot and round in the second buffer
_COMPACT_MIN = 1024  # arrays with fewer entries run whole-array rounds (buffer_sizes)


class ShapeTerms(NamedTuple):
    """Per-entry constants of the boosted shape ``a'``: ``d = a' - 1/3``, ``ln d``, ``sqrt(2) c = 1 / sqrt(4.5 d)``
    and ``1 / a`` for boosted entries (0 for ``a >= 1``)."""

    d: jax.Array
    log_d: jax.Array
    c2: jax.Array
    inv_a: jax.Array

    def take(self, index: jax.Array) -> ShapeTerms:
        return ShapeTerms(*(jnp.take(x, index, mode="clip") for x in self))


def shape_terms(a: jax.Array) -> ShapeTerms:
    small = a < 1.0
    d = jnp.where(small, a + 1.0, a) - 1.0 / 3.0
    # 1/a overflows for subnormal shapes; the largest float keeps 0 * inv_a = 0 (the boost of a trial with U = 1).
    inv_a = jnp.where(small, jnp.minimum(1.0 / a, jnp.finfo(a.dtype).max), 0.0)
    return ShapeTerms(d, jnp.log(d), jax.lax.rsqrt(4.5 * d), inv_a)


def trial_log_gamma(e: jax.Array, w: jax.Array, shape: ShapeTerms) -> tuple[jax.Array, jax.Array]:
    """One Marsaglia-Tsang trial per entry from its deviates: ``e = x / sqrt(2)`` (``x ~ N(0, 1)``) and ``w`` uniform
    on ``(0, 1]``, arrays of one shape. Returns ``(accept, ln G)``, ``ln G`` meaningful where accepted (with the
    recycled boost for shapes below one; module docstring)."""
    dtype = shape.d.dtype
    x = np.sqrt(2.0).astype(dtype) * e
    y = 1.0 + shape.c2 * e  # 1 + c x
    v = y * y * y
    positive = v > 0
    log_v = jnp.log(jnp.where(positive, v, 1.0))
    log_w = jnp.log(w)
    log_t = 0.5 * x * x + shape.d * (1.0 - v + log_v)
    accept = positive & ((w < 1.0 - 0.0331 * (x * x) * (x * x)) | (log_w < log_t))
    # Recycled boost: ln U = ln w - ln t(x) <= 0 (the minimum absorbs rounding of squeeze-accepted trials).
    return accept, shape.log_d + log_v + jnp.minimum(log_w - log_t, 0.0) * shape.inv_a


def trial_deviates(key: jax.Array, n: int, dtype: jax.typing.DTypeLike) -> tuple[jax.Array, jax.Array]:
    """A trial's deviates for ``n`` entries: ``e = erf_inv(v)`` with ``v`` uniform on ``(-1, 1)`` (so that ``sqrt(2)
    e ~ N(0, 1)``) and ``w`` uniform on ``(0, 1]``, from one Threefry-2x32 hash per entry (two in float64) of the
    counter ``(i, 0)`` (and ``(i, 1)``) under two key words drawn from ``key``, written out by
    :func:`~jaxmdp.sampling.threefry.threefry2x32` so that XLA fuses the hash with the trial's arithmetic. This is
    done because the random words alone as two ``jax.random.uniform`` arrays, whose rolled hash loop goes through
    memory, cost several times the whole fused trial, ``erf_inv`` included (docs/performance.md, Sampling). The words
    become deviates in :func:`deviates_from_words`."""
    words = jax.random.bits(key, (2,), jnp.uint32)
    i = jax.lax.iota(jnp.uint32, n)
    b0, b1 = threefry2x32(words[0], words[1], i, np.uint32(0))
    if dtype == jnp.float64:
        b2, b3 = threefry2x32(words[0], words[1], i, np.uint32(1))
        return deviates_from_words(join_words(b0, b1), join_words(b2, b3))
    return deviates_from_words(b0, b1)


def deviates_from_words(m0: jax.Array, m1: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``(erf_inv(v), w)`` from random words, float32 from ``uint32`` words and float64 from ``uint64`` ones: with
    ``u0, u1`` their :func:`~jaxmdp.sampling.threefry.unit_floats` on ``[0, 1)``, ``v = 2 u0 - 1`` on the grid of
    ``2^-22`` (``2^-51`` in float64) with ``-1`` moved to the next float up (``erf_inv(-1)`` is infinite), and
    ``w = 1 - u1``, on ``(0, 1]``. Every operation is exact (its result is on the float grid), so no compiler
    contraction can change it between scalar and vector code. The normal's tails stop where ``jax.random.normal``'s
    do (module docstring)."""
    dtype = jnp.float64 if m0.dtype == jnp.uint64 else jnp.float32
    lo = np.nextafter(np.array(-1.0, dtype), np.array(0.0, dtype))
    v = jnp.maximum(np.array(2.0, dtype) * unit_floats(m0, dtype) - np.array(1.0, dtype), lo)
    return jax.lax.erf_inv(v), np.array(1.0, dtype) - unit_floats(m1, dtype)


def _trial(key: jax.Array, shape: ShapeTerms) -> jax.Array:
    """One trial for each entry of ``shape`` (a flat array of ``n``), its deviates from :func:`trial_deviates`:
    ``ln G`` where accepted, NaN where rejected."""
    e, w = trial_deviates(key, shape.d.shape[0], shape.d.dtype)
    accept, log_g = trial_log_gamma(e, w, shape)
    return jnp.where(accept, log_g, jnp.nan)


def _candidates(count: int, shape: ShapeTerms) -> ShapeTerms:
    """Shape terms of ``count`` trials per entry as one flat array, candidate-major (trial ``c`` of entry ``i`` at
    ``c * n + i``). A flat ``count * n`` array keeps the innermost dimension long enough for XLA to vectorise under
    ``vmap`` when ``n`` is small (the two Gammas of a Beta)."""
    return ShapeTerms(*(jnp.tile(x, count) for x in shape))


def _first_of(trials: jax.Array, count: int, log_g: jax.Array) -> jax.Array:
    """Entries still NaN in ``log_g`` take their first accepted trial of ``trials`` (``count`` per entry, laid out by
    :func:`_candidates`), or stay NaN."""
    trials = trials.reshape(count, -1)
    first = trials[count - 1]
    for c in range(count - 2, -1, -1):
        first = jnp.where(jnp.isnan(trials[c]), first, trials[c])
    return jnp.where(jnp.isnan(log_g), first, log_g)


def _rounds(key: jax.Array, tag0: int, shape: ShapeTerms, count: int, log_g: jax.Array) -> jax.Array:
    """Rounds of ``count`` trials per entry (round ``r`` on the key ``fold_in(key, tag0 + r)``; ``shape`` laid out by
    :func:`_candidates`) until every entry of ``log_g`` is accepted; entries already accepted keep their value.

    The raw trials of a round are loop state, taken into ``log_g`` at the next check: a round's trials are then
    written out in their own (vectorised) loop instead of being fused, index by index, into the selection of each
    entry's first accepted trial.
    """
    def body(carry):
        r, log_g, trials = carry
        return r + 1, _first_of(trials, count, log_g), _trial(jax.random.fold_in(key, tag0 + r), shape)

    pending = lambda carry: jnp.any(jnp.isnan(_first_of(carry[2], count, carry[1])))  # noqa: E731
    init = (jnp.int32(0), log_g, jnp.full(shape.d.shape, jnp.nan, log_g.dtype))
    _, log_g, trials = jax.lax.while_loop(pending, body, init)
    return _first_of(trials, count, log_g)


def _compacted_pass(
    key: jax.Array, log_g: jax.Array, a: jax.Array, m1: int, m2: int
) -> tuple[jax.Array, jax.Array]:
    """A pass over the rejected (NaN) entries of ``log_g`` (shapes ``a``) with the pass's own ``key``: two compacted
    buffers. Returns ``log_g`` and whether a buffer overflowed, leaving some entries NaN (from the compactions'
    counts, without reading ``log_g`` again)."""
    idx1, in1, rejected1 = compact_with_count(jnp.isnan(log_g), m1)
    shape1 = shape_terms(jnp.take(a, idx1, mode="clip"))
    log_g1 = jnp.where(in1, _trial(jax.random.fold_in(key, 0), shape1), 0.0)  # empty slots: 0, never retried
    idx2, in2, rejected2 = compact_with_count(jnp.isnan(log_g1), m2)
    shape2 = _candidates(_FINE_CANDIDATES, shape1.take(idx2))
    pending2 = jnp.where(in2, jnp.nan, 0.0).astype(log_g.dtype)  # empty slots: 0, never retried
    log_g2 = _rounds(key, 1, shape2, _FINE_CANDIDATES, pending2)
    log_g1 = log_g1.at[idx2].set(log_g2, mode="drop", unique_indices=True)
    log_g = log_g.at[idx1].set(log_g1, mode="drop", unique_indices=True)
    return log_g, (rejected1 > m1) | (rejected2 > m2)


def buffer_sizes(n: int) -> tuple[int, int]:
    """Default buffer sizes ``(m1, m2) = (n // 16 + 64, m1 // 16 + 64)`` for an array of ``n`` entries; ``(n, n)``
    (no compaction) below 1024 entries, where rounds of four candidates over the whole array cost little more and
    compile in a third of the time."""
    if n < _COMPACT_MIN:
        return n, n
    m1 = n // 16 + 64
    return m1, m1 // 16 + 64


@functools.partial(jax.jit, static_argnames=("candidates", "dtype", "buffers"))
def sample_log_gamma(
    key: jax.Array,
    a: jax.Array,
    *,
    candidates: int | None = None,
    dtype=jnp.float32,
    buffers: tuple[int, int] | None = None,
) -> jax.Array:
    """``ln G`` with ``G ~ Gamma(a, 1)`` elementwise, for shapes ``a > 0`` of any array shape.

    ``candidates``: trials per entry in each whole-array round; default 1 for arrays large enough to compact their
    rejections (``m1 < n``), else :data:`DEFAULT_CANDIDATES`. ``buffers``: the compaction buffer sizes ``(m1, m2)``
    (default :func:`buffer_sizes`); tiny sizes force the overflow path (tests). Method, stream and guarantees: the
    module docstring.
    """
    a = jnp.asarray(a, dtype)
    out_dtype = a.dtype
    work = jnp.float64 if out_dtype == jnp.float64 else jnp.float32
    flat = a.reshape(-1).astype(work)
    n = flat.shape[0]
    if n == 0:
        return jnp.zeros(a.shape, out_dtype)
    if n >= 2**31 - 2**20:  # int32 compaction indices
        raise ValueError(f"sample_log_gamma: a has {n} entries; fewer than 2**31 - 2**20 are supported")
    m1, m2 = buffer_sizes(n) if buffers is None else buffers
    if m1 < 1 or m2 < 1:
        raise ValueError(f"sample_log_gamma: buffers must be positive, got {(m1, m2)}")
    m2 = min(m2, m1)
    compacted = m1 < n
    if candidates is None:
        candidates = 1 if compacted else DEFAULT_CANDIDATES
    if candidates < 1:
        raise ValueError(f"sample_log_gamma: candidates must be >= 1, got {candidates}")

    proper = (flat > 0) & (flat < jnp.inf)
    flat_ok = jnp.where(proper, flat, 1.0)
    stream = jax.random.fold_in(key, _STREAM)
    shape = shape_terms(flat_ok)
    if compacted:
        # One round over the whole array, then compacted passes over its rejected entries while a buffer overflowed
        # (the compactions' counts say so; the first pass always runs). A loop on "some entry is NaN" read every
        # member's whole array twice under vmap (module docstring).
        log_g = _first_of(_trial(jax.random.fold_in(stream, 0), _candidates(candidates, shape)), candidates,
                          jnp.full((n,), jnp.nan, work))

        def body(carry):
            p, _, log_g = carry
            log_g, left = _compacted_pass(jax.random.fold_in(stream, p + 1), log_g, flat_ok, m1, m2)
            return p + 1, left, log_g

        log_g = jax.lax.while_loop(lambda c: c[1], body, (jnp.int32(0), jnp.ones((), bool), log_g))[2]
    else:
        log_g = _rounds(stream, 0, _candidates(candidates, shape), candidates, jnp.full((n,), jnp.nan, work))
    improper = jnp.where(flat == 0, -jnp.inf, jnp.where(flat == jnp.inf, jnp.inf, jnp.nan))
    return jnp.where(proper, log_g, improper).astype(out_dtype).reshape(a.shape)


@functools.partial(jax.jit, static_argnames=("candidates", "dtype"))
def sample_beta(
    key: jax.Array, a: jax.Array, b: jax.Array, *, candidates: int = DEFAULT_CANDIDATES, dtype=jnp.float32
) -> jax.Array:
    """One ``Beta(a, b) = G_a / (G_a + G_b)`` draw for scalar ``a, b > 0`` (vmap for more), from the logs of the two
    Gammas (one :func:`sample_log_gamma` call, entries 0 and 1) without overflow."""
    a, b = jnp.asarray(a, dtype), jnp.asarray(b, dtype)
    log_a, log_b = sample_log_gamma(key, jnp.stack([a, b]), candidates=candidates, dtype=dtype)
    top = jnp.maximum(log_a, log_b)
    ea, eb = jnp.exp(log_a - top), jnp.exp(log_b - top)
    return ea / (ea + eb)
