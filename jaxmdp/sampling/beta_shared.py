"""The step's reward sampler (:func:`jaxmdp.env.sample_reward`): exact Beta draws, one pair of shapes at a time,
``Beta(a, b) = G_a / (G_a + G_b)`` with the two Gammas taken from one sequence of Marsaglia-Tsang trials.

**Why.** The environment draws one Beta per step and environment: two shapes per member under ``vmap``. Drawn with
:func:`jaxmdp.sampling.beta_sampling.sample_beta` (rounds of four trials per Gamma inside a ``while_loop``: a
``fold_in``, and per round a ``fold_in``, a ``split`` and two ``uniform`` arrays of eight: 20 Threefry hashes), the draw
costs more than the rest of a step (docs/performance.md, Environment step). Three things make it slow on CPU, and this
sampler avoids each: every ``jax.random`` call is a rolled loop over memory (:mod:`jaxmdp.sampling.threefry`), arrays of
a few entries per member vectorise badly under ``vmap`` (the member axis is not the innermost one; XLA also splits their
fusions), and the round loop runs at every step. Here a round is ``trials`` (default 4) trials in scalar code, each from
one unrolled Threefry hash, round 0 sits outside the loop, and a second round is needed at under 0.05% of the draws, so
the step runs several times faster on the families with Beta rewards than with
:func:`~jaxmdp.sampling.beta_sampling.sample_beta` (docs/performance.md, Environment step).

**Batches.** A member of a ``vmap``-ed batch gets bit for bit its value alone (the project's guarantee that batched
trajectories equal single runs, tests/test_env.py), which scalar code alone does not give on XLA CPU: a single call (and
a ``vmap`` over one member) is compiled as scalar code, a batch of two or more members as vectorised loops, and the two
round differently. Measured (256 draws, each intermediate taken out as an output): the uniforms, ``erf_inv``, ``x``, ``1
+ c x``, ``v``, ``ln v``, ``ln w`` and the shape terms agree bit for bit, ``ln t(x) = x^2 / 2 + d (1 - v + ln v)``
differs in 254 of 256 (the batch computes ``fma(x / 2, x, d (1 - v + ln v))`` in all 256; the scalar code none of the
simple contractions tried), ``ln G`` in 6; with everything fused about 4% of the draws differ in the last bits, some in
an acceptance. XLA emits the same LLVM IR for both apart from the vector types (for a kernel of ``ln t(x)``: 63
``fadd``, 67 against 68 ``fmul``, no FMA, ``rsqrtss`` against ``vrsqrtps``); the multiply-adds are contracted into FMAs
by the x86 back end, differently for scalar and vector code. Batches of 2, 3, 4, 7, 8, 16, 60 and 255 members all give
the bits of a batch of 1024: only the one-member case differs. Hence a ``jax.custom_batching.custom_vmap`` rule: a
single call evaluates the vectorised code of a batch of two, itself and a dummy member (fixed key words, shapes 1,
accepted in round 0, tested), and keeps its own value; under ``vmap`` a batch runs the vectorised code as is, with the
dummy member appended when it has one member or when an argument is shared by the members (a ``vmap`` with
``in_axes=None``: XLA would compute the broadcast shape's terms once, in scalar code). Nested ``vmap``, ``lax.map``,
``jit`` and eager calls keep the property (tests/test_beta_rewards.py); the speed is that of the plain scalar sampler
(docs/performance.md, Sampling). Broadcasting one member to a batch of eight does not work instead: XLA moves the
arithmetic before the broadcast. Shapes that are compile-time constants (closed over, not arguments) are folded by XLA
on the host and may differ in the last bits from the same shapes passed as arguments, as for
:mod:`~jaxmdp.sampling.beta_sampling`. No gradient rule: the sampler is not differentiable (nor needs to be).

**Method.** Trials ``1, 2, ...`` are i.i.d.: trial ``j`` has the normal ``x_j = sqrt(2) erf_inv(2 u_j - 1)`` and the
uniform ``w_j = 1 - u'_j`` on ``(0, 1]`` (the Marsaglia-Tsang trial of :mod:`~jaxmdp.sampling.beta_sampling`,
:func:`~jaxmdp.sampling.beta_sampling.trial_log_gamma`, with its boost for shapes below one). In a round of ``n``
trials, the trials go to ``G_a`` until one is accepted for shape ``a``, the following ones to ``G_b`` until one is
accepted for shape ``b``; a round that does not accept both is discarded and the next round drawn. This is exact: on
the event that ``G_a`` takes trial ``j`` and ``G_b`` trial ``k > j``, which depends only on which trials are accepted,
the values are those of trials ``j`` and ``k``, and an accepted trial's value has the exact Gamma law whatever the
acceptances of the other trials (``P(T_j accepted for a, value in A) = P(accepted) Gamma_a(A)``); summed over the
pairs ``j < k``, the round's success is independent of ``(G_a, G_b)``, which are independent with the Gamma laws, and
rounds are independent. Every trial is accepted with probability ``p > 0.95`` (worst at ``a' = 1``: 0.9517), so a
round fails with probability at most ``q^n + n p q^(n-1)`` (``q = 1 - p``): 4.4e-4 for ``n = 4`` (2.6e-5 for ``n =
5``, 1.5e-6 for ``n = 6``), much less for shapes away from 1 (0 seen in 2 M draws of Beta(0.8, 20) at ``n = 5``).
Under ``vmap`` the loop over further rounds runs at a step as soon as one member needs it (for all members): with
1024 members at the worst shapes, at about a third of the steps with ``n = 4`` and 3% with ``n = 5``; four trials are
the fastest at 1024 environments on the families (docs/performance.md, Sampling). Trial 0 can only be
``G_a``'s and the last trial is only useful to ``G_b``, so a round evaluates ``2 n - 2`` trial tests.

**Rounds before the loop.** Round 0 runs for every member before the ``while_loop``; ``unrolled_rounds = k`` runs
rounds ``0 .. k-1`` there (each member keeps its first successful one) and the loop starts at round ``k``. The value is
the same, the first successful round's, whatever ``k`` (tested bit for bit): only the cost moves. On a CPU the loop
is cheap and an extra round costs the whole batch another round of arithmetic, so the step uses ``k = 1``. On a GPU
each trip of a ``while_loop`` is its own kernel launches with its predicate read back, and with 1 024 members some
member needs round 1 at about a third of the steps (above): ``k = 2`` would leave the loop a single predicate check
at nearly every step. On a GPU ``k = 2`` pays with the worst shapes but costs with the benchmark's mixed ones, so the
step keeps ``k = 1`` on every platform (docs/performance.md, GPU).

**Random numbers.** Threefry-2x32 of the key (the function ``jax.random`` uses;
:func:`jaxmdp.sampling.threefry.threefry2x32`) on the counters ``(T, j)``, ``T = 0x62657461`` ("beta"): trial ``j``
(counted over rounds) uses both 32-bit words of the hash of counter ``j``, the first for ``u_j`` and the second for
``u'_j`` (``jax.random`` keeps one 32-bit word per hash, the XOR of the two). ``jax.random`` hashes counters whose high
word is 0 (``split``, ``fold_in``, ``bits`` of arrays below ``2^32`` entries), so the sampler never reuses a hash that a
``jax.random`` call on the same key computes. Uniforms take a word's top 23 bits (float32) as ``jax.random.uniform``
does; float64 trials take one 64-bit word (both words of a hash, top 52 bits) per uniform, from counters ``2 j`` and ``2
j + 1``. Keys of another implementation (``rbg``) draw trial ``j``'s words with ``jax.random.bits(fold_in(key, j))``. As
``jax.random.normal``, ``x`` stops at about 5.4 (``P(|x| > 5.4) ~ 7e-8``).

**Same key, same value.** The value is a function of the key, the shapes and ``trials``, whether drawn alone or as a
member of a batch ("Batches").

**Bad input.** As :func:`~jaxmdp.sampling.beta_sampling.sample_log_gamma`: a zero shape is a Gamma of 0 (``ln G =
-inf``), an infinite one ``+inf``, a negative or NaN one NaN; such shapes are drawn as shape 1 and replaced, so
nothing hangs. Hence ``Beta(0, b) = 0`` and ``Beta(a, 0) = 1`` for proper ``a, b``, NaN for any other improper pair
(infinite shapes included), as before.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp.sampling.beta_sampling import ShapeTerms, shape_terms, trial_log_gamma
from jaxmdp.sampling.threefry import join_words, threefry2x32, unit_floats

__all__ = ["sample_beta_shared", "DEFAULT_TRIALS"]

#: Trials per round (module docstring: a round fails with probability at most 4.4e-4).
DEFAULT_TRIALS = 4

_TAG = np.uint32(0x62657461)  # high word of the sampler's Threefry counters (jax.random's are 0)


def _trial_uniforms(key: jax.Array, j: jax.Array, dtype) -> tuple[jax.Array, jax.Array]:
    """The uniforms ``(u_j, u'_j)`` on ``[0, 1)`` of trial ``j``, scalars (module docstring, "Random numbers")."""
    data = jax.random.key_data(key)
    wide = np.dtype(dtype).itemsize == 8
    typed = jnp.issubdtype(key.dtype, jax.dtypes.prng_key)
    if (typed and str(jax.random.key_impl(key)) != "threefry2x32") or data.shape != (2,):
        bits = jax.random.bits(jax.random.fold_in(key, j), (2,), jnp.uint64 if wide else jnp.uint32)
        return unit_floats(bits[0], dtype), unit_floats(bits[1], dtype)
    j = j.astype(jnp.uint32)
    if not wide:
        hi, lo = threefry2x32(data[0], data[1], _TAG, j)
        return unit_floats(hi, dtype), unit_floats(lo, dtype)
    pair = []
    for c in (2 * j, 2 * j + 1):
        hi, lo = threefry2x32(data[0], data[1], _TAG, c)
        pair.append(unit_floats(join_words(hi, lo), dtype))
    return pair[0], pair[1]


def _round(key: jax.Array, r: jax.Array, n: int, ab: jax.Array, shapes: tuple[ShapeTerms, ShapeTerms]) -> jax.Array:
    """The Beta draw of round ``r`` (trials ``r n .. r n + n - 1`` given in order to ``G_a`` until one is accepted,
    then to ``G_b``), or -1 where the round did not accept both (module docstring). Scalar code, so that under
    ``vmap`` every operation runs over the members."""
    shape_a, shape_b = shapes
    dtype = shape_a.d.dtype
    lo = np.nextafter(np.array(-1.0, dtype), np.array(0.0, dtype))
    has_a = has_b = jnp.zeros((), bool)
    log_a = log_b = jnp.zeros((), dtype)
    for i in range(n):
        u, u2 = _trial_uniforms(key, r * n + i, dtype)
        e = jax.lax.erf_inv(jnp.maximum(2.0 * u - 1.0, lo))  # x / sqrt(2), x standard normal
        w = 1.0 - u2  # uniform on (0, 1]
        if i > 0:  # trial 0 is always G_a's
            accept_b, trial_b = trial_log_gamma(e, w, shape_b)
            to_b = has_a & ~has_b & accept_b  # G_b's only if G_a was accepted before it
            log_b, has_b = jnp.where(to_b, trial_b, log_b), has_b | to_b
        if i < n - 1:  # G_a accepted at the last trial leaves nothing for G_b: the round fails either way
            accept_a, trial_a = trial_log_gamma(e, w, shape_a)
            to_a = ~has_a & accept_a
            log_a, has_a = jnp.where(to_a, trial_a, log_a), has_a | to_a
    proper = (ab > 0) & (ab < jnp.inf)
    improper = jnp.where(ab == 0, -jnp.inf, jnp.where(ab == jnp.inf, jnp.inf, jnp.nan))
    log_a = jnp.where(proper[0], log_a, improper[0])
    log_b = jnp.where(proper[1], log_b, improper[1])
    top = jnp.maximum(log_a, log_b)
    ea, eb = jnp.exp(log_a - top), jnp.exp(log_b - top)
    return jnp.where(has_a & has_b, ea / (ea + eb), -1.0)


def _draw(
    data: jax.Array, a: jax.Array, b: jax.Array, *, trials: int, impl: str | None, unrolled: int = 1
) -> jax.Array:
    """The draw of one key (its raw words ``data``; ``impl`` the name of a typed key's implementation, None for a raw
    key) and one pair of shapes (scalars of the working dtype): scalar code, meant to run under ``vmap``. Rounds ``0
    .. unrolled - 1`` run before the loop (module docstring, "Rounds before the loop")."""
    key = data if impl is None else jax.random.wrap_key_data(data, impl=impl)
    ab = jnp.stack([a, b])
    ok = jnp.where((ab > 0) & (ab < jnp.inf), ab, 1.0)  # improper shapes are drawn as 1, then replaced
    shapes = (shape_terms(ok[0]), shape_terms(ok[1]))
    # Round 0 outside the loop: under vmap the loop then runs only at the steps where some member needs it. The loop
    # carries one value per member (the draw, -1 while missing), which lets XLA fuse round 0 into a single loop.
    first = _round(key, jnp.int32(0), trials, ab, shapes)
    for r in range(1, unrolled):
        first = jnp.where(first < 0, _round(key, jnp.int32(r), trials, ab, shapes), first)
    _, draw = jax.lax.while_loop(
        lambda carry: carry[1] < 0,
        lambda carry: (carry[0] + 1, _round(key, carry[0], trials, ab, shapes)),
        (jnp.int32(unrolled), first),
    )
    return draw


def _padded(args: tuple[jax.Array, jax.Array, jax.Array], dummy: tuple[np.ndarray, np.ndarray, np.ndarray]):
    """``args`` (a leading axis of members) with one dummy member appended: a batch that XLA cannot treat as one
    element (module docstring, "Batches")."""
    return tuple(jnp.concatenate([x, jnp.asarray(d, x.dtype)[None]]) for x, d in zip(args, dummy))


@functools.lru_cache(maxsize=None)
def _lanes(trials: int, impl: str | None, key_words: int, dtype, unrolled: int = 1) -> Callable:
    """The sampler of one key and pair of shapes as a ``custom_vmap`` function of ``(key words, a, b)`` that always
    evaluates the vectorised code of a batch of at least two members: alone, with a dummy member appended; under
    ``vmap``, over the batch (with a dummy member if it has one member or shares an argument)."""
    draws = jax.vmap(functools.partial(_draw, trials=trials, impl=impl, unrolled=unrolled))
    # Raw key words and shapes of the dummy member; shape 1 with these words is accepted in round 0 (tested).
    dummy = (np.arange(1, key_words + 1, dtype=np.uint32), np.array(1.0, dtype), np.array(1.0, dtype))

    @jax.custom_batching.custom_vmap
    def lanes(data, a, b):
        return draws(*_padded((data[None], a[None], b[None]), dummy))[0]

    @lanes.def_vmap
    def _batched(axis_size, in_batched, data, a, b):
        args = tuple(x if batched else jnp.broadcast_to(x, (axis_size, *x.shape))
                     for x, batched in zip((data, a, b), in_batched))
        if axis_size == 1 or not all(in_batched):  # (a broadcast member's arithmetic may be hoisted to scalar code)
            return draws(*_padded(args, dummy))[:axis_size], True
        return draws(*args), True

    return lanes


@functools.partial(jax.jit, static_argnames=("trials", "dtype", "unrolled_rounds"))
def sample_beta_shared(
    key: jax.Array,
    a: jax.Array,
    b: jax.Array,
    *,
    trials: int = DEFAULT_TRIALS,
    dtype=jnp.float32,
    unrolled_rounds: int = 1,
) -> jax.Array:
    """One ``Beta(a, b) = G_a / (G_a + G_b)`` draw for scalar shapes ``a, b > 0`` (``vmap`` for more), exact.

    ``G_a``, ``G_b`` (``Gamma(shape, 1)``, kept as logs so that tiny shapes do not underflow) are the first accepted
    Marsaglia-Tsang trials of one shared sequence, in rounds of ``trials >= 2`` trials, a round that does not accept
    both being drawn again (module docstring). Returns the draw in ``dtype`` (float32, or float64 with x64); a member
    of a ``vmap``-ed batch gets bit for bit its value alone. ``unrolled_rounds``: rounds computed for every member
    before the loop over further rounds (module docstring, "Rounds before the loop"); the value does not depend on it.
    """
    if unrolled_rounds < 1:
        raise ValueError(
            f"sample_beta_shared: unrolled_rounds must be >= 1 (round 0 always runs), got {unrolled_rounds}"
        )
    if trials < 2:
        raise ValueError(f"sample_beta_shared: trials must be >= 2 (one trial per Gamma at least), got {trials}")
    a, b = jnp.asarray(a, dtype), jnp.asarray(b, dtype)
    if a.shape != () or b.shape != ():
        raise ValueError(
            f"sample_beta_shared: a and b must be scalars (vmap for more); got shapes {a.shape}, {b.shape}"
        )
    work = jnp.float64 if a.dtype == jnp.float64 else jnp.float32
    typed = jnp.issubdtype(key.dtype, jax.dtypes.prng_key)
    data = jax.random.key_data(key) if typed else key
    impl = str(jax.random.key_impl(key)) if typed else None
    lanes = _lanes(trials, impl, data.shape[0], np.dtype(work), unrolled_rounds)
    return lanes(data, a.astype(work), b.astype(work)).astype(a.dtype)
