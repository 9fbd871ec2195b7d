"""The Gamma/Beta sampler as it was before compaction (jaxmdp/beta_sampling.py at commit 8e9fd47), kept unchanged
so that scripts/bench_sampling.py can time old and new in one process. Not used by the package.

Exact Beta and log-Gamma variates that vectorise well: rejection sampling with a block of candidates per round.

The one Gamma sampler of the project: environment rewards (Beta) and the agents' Dirichlet and Normal-Gamma
posterior draws (:mod:`agents.posteriors`) both use it.

``jax.random.beta`` draws two Gammas with Marsaglia and Tsang's rejection method as a ``while_loop`` that splits its
key at every trial; under ``vmap`` over thousands of lockstep members every lane then waits for the slowest one and
pays a key split per trial, which made Beta rewards ~90% of an environment step. Here the same method runs on a
block of ``candidates`` trials drawn with one call:

* Marsaglia & Tsang (2000) for shape ``a' >= 1``: ``d = a' - 1/3``, ``c = 1 / sqrt(9 d)``; a trial draws
  ``x ~ N(0, 1)`` and ``w ~ U(0, 1]``, sets ``v = (1 + c x)^3`` and accepts ``d v`` when ``v > 0`` and
  ``w < 1 - 0.0331 x^4`` (squeeze) or ``ln w < x^2 / 2 + d (1 - v + ln v)``. Every trial is accepted with probability
  above 0.95 (worst at ``a' = 1``);
* shapes ``a < 1`` are boosted: ``Gamma(a) = Gamma(a + 1) U^(1/a)``, computed in log space so that tiny shapes
  (Colosseum uses ``a = 0.01``) do not underflow: ``ln G = ln(d v) + ln(U) / a``;
* the result is the *first* accepted trial of the block. Trials are i.i.d., so this is exactly rejection sampling;
  if no trial of the block is accepted (probability below ``0.05^4 < 7e-6`` with 4 candidates) further blocks are
  drawn: under ``vmap`` the loop usually runs once for all lanes;
* ``Beta(a, b) = G_a / (G_a + G_b)``, evaluated from the logs without overflow.

Round ``i`` draws its uniforms from ``fold_in(key, i)``, so draws are independent of anything else drawn with
``key`` itself. Every round, the first included, runs inside the ``while_loop`` body: XLA then compiles the same
arithmetic for a batched and an unbatched call, and a member of a ``vmap``-ed batch gets bit-for-bit the value it
would get alone (fused with its neighbours, the arithmetic was rewritten differently for the two and differed in
the last bit).

The values are exact draws from the distributions (up to floating-point rounding, as for ``jax.random``); the
random stream differs from ``jax.random.beta``'s.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["sample_log_gamma", "sample_beta", "DEFAULT_CANDIDATES"]

#: Trials drawn per round: with acceptance > 0.95 a round fails with probability < 7e-6.
DEFAULT_CANDIDATES = 4

# fold_in index of the boost uniforms (rounds use 0, 1, 2, ... and never get near it).
_BOOST_STREAM = 2**31 - 1


def _log_gamma_round(u: jax.Array, a: jax.Array, candidates: int) -> tuple[jax.Array, jax.Array]:
    """One round from ``u[2 * candidates, *a.shape]`` uniforms in ``[0, 1)``: ``(accepted, ln(d v))`` per entry for
    the boosted shape (``a + 1`` where ``a < 1``); :func:`_log_boost` adds the boost."""
    dtype = u.dtype
    d = jnp.where(a < 1.0, a + 1.0, a) - 1.0 / 3.0
    c = jax.lax.rsqrt(9.0 * d)
    # N(0, 1) by inversion; u = 0 gives x = -inf, which the v > 0 test rejects.
    x = jnp.sqrt(jnp.asarray(2.0, dtype)) * jax.lax.erf_inv(2.0 * u[:candidates] - 1.0)
    w = 1.0 - u[candidates:]  # uniform on (0, 1]
    v = (1.0 + c * x) ** 3
    positive = v > 0
    log_v = jnp.log(jnp.where(positive, v, 1.0))
    accept = positive & ((w < 1.0 - 0.0331 * x**4) | (jnp.log(w) < 0.5 * x * x + d * (1.0 - v + log_v)))
    if candidates == 1:
        log_v_first = log_v[0]
    else:
        first = jnp.argmax(accept, axis=0)
        log_v_first = jnp.take_along_axis(log_v, first[None], axis=0)[0]
    return jnp.any(accept, axis=0), jnp.log(d) + log_v_first


def _log_boost(key: jax.Array, a: jax.Array) -> jax.Array:
    """``ln U / a`` where ``a < 1`` (``Gamma(a) = Gamma(a + 1) U^(1/a)``), else 0; one uniform per entry."""
    u = jax.random.uniform(jax.random.fold_in(key, _BOOST_STREAM), a.shape, a.dtype)
    return jnp.where(a < 1.0, jnp.log1p(-u) / a, 0.0)


def sample_log_gamma(
    key: jax.Array, a: jax.Array, *, candidates: int = DEFAULT_CANDIDATES, dtype=jnp.float32
) -> jax.Array:
    """``ln G`` with ``G ~ Gamma(a, 1)`` elementwise, for shapes ``a > 0`` of any array shape.

    All entries draw their blocks together and the loop repeats until every entry has accepted a trial; an entry
    keeps the trial it accepted first, so its value does not depend on how many rounds the others needed. For large
    arrays (posterior draws) ``candidates=1`` is fastest: memory traffic, not arithmetic, bounds the cost.
    """
    a = jnp.asarray(a, dtype)

    def round_(carry):
        i, ok, log_g = carry
        u = jax.random.uniform(jax.random.fold_in(key, i), (2 * candidates, *a.shape), dtype)
        ok_new, log_new = _log_gamma_round(u, a, candidates)
        return i + 1, ok | ok_new, jnp.where(ok, log_g, log_new)

    init = (jnp.int32(0), jnp.zeros(a.shape, bool), jnp.zeros(a.shape, dtype))
    return jax.lax.while_loop(lambda c: ~jnp.all(c[1]), round_, init)[2] + _log_boost(key, a)


def sample_beta(
    key: jax.Array, a: jax.Array, b: jax.Array, *, candidates: int = DEFAULT_CANDIDATES, dtype=jnp.float32
) -> jax.Array:
    """One ``Beta(a, b)`` draw for scalar ``a, b > 0`` (vmap for more); both Gammas share one uniform block."""
    a, b = jnp.asarray(a, dtype), jnp.asarray(b, dtype)
    n = 2 * candidates

    def round_(carry):
        i, ok_a, log_a, ok_b, log_b = carry
        u = jax.random.uniform(jax.random.fold_in(key, i), (2 * n,), dtype)
        ok_a2, log_a2 = _log_gamma_round(u[:n], a, candidates)
        ok_b2, log_b2 = _log_gamma_round(u[n:], b, candidates)
        return i + 1, ok_a | ok_a2, jnp.where(ok_a, log_a, log_a2), ok_b | ok_b2, jnp.where(ok_b, log_b, log_b2)

    no, zero = jnp.zeros((), bool), jnp.zeros((), dtype)
    _, _, log_a, _, log_b = jax.lax.while_loop(lambda c: ~(c[1] & c[3]), round_, (jnp.int32(0), no, zero, no, zero))
    boost = _log_boost(key, jnp.stack([a, b]))
    log_a, log_b = log_a + boost[0], log_b + boost[1]
    top = jnp.maximum(log_a, log_b)
    ea, eb = jnp.exp(log_a - top), jnp.exp(log_b - top)
    return ea / (ea + eb)
