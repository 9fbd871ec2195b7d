"""Emission noise: the four kinds of paper App. A.2 (light/heavy tailed x uncorrelated/correlated).

An observation is ``o = q(s) + e`` with ``q(s)`` the emission-table row of the state and ``e`` one draw of the noise,
taken from the step's key. With ``d`` the number of components of an observation:

* ``"gaussian"``: ``e_i ~ N(0, scale^2)`` i.i.d. (default ``scale = 0.1``);
* ``"student_t"``: ``e_i = scale * t_i``, ``t_i ~ Student-t(df)`` i.i.d. per component (defaults ``df = 3``,
  ``scale = 1``: the reference draws unscaled ``standard_t(3)`` values). The reference hands out one scalar per
  observation, the same for every component; the paper's intent, element-wise noise, is what is drawn here;
* ``"correlated_gaussian"``: ``e ~ N(0, W)``, reshaped to the observation's shape, where ``W ~ Wishart(d, scale I_d)``
  is drawn once when the BlockMDP is made (default ``scale = 0.1``, so ``E[W] = d * scale * I_d``);
* ``"correlated_student_t"``: multivariate Student-t with shape matrix ``W`` (drawn as above) and ``df`` degrees of
  freedom, ``e = L z / sqrt(u / df)`` with ``W = L L^T``, ``z ~ N(0, I_d)`` and one ``u ~ chi^2(df)`` per observation
  (defaults ``scale = 0.1``, ``df = 1``, scipy's ``multivariate_t`` default used by the reference).

The Wishart matrix is kept as its Cholesky factor ``L``, which Bartlett's decomposition yields directly, so that each
correlated draw is one matrix-vector product.
"""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp

from jaxmdp._checks import did_you_mean

__all__ = [
    "NOISE_KINDS",
    "NOISE_DEFAULTS",
    "CORRELATED_NOISE_KINDS",
    "check_noise_kind",
    "noise_parameters",
    "wishart_cholesky",
    "sample_noise",
]

#: The noise kinds, in the paper's order (App. A.2).
NOISE_KINDS = ("gaussian", "correlated_gaussian", "student_t", "correlated_student_t")
#: The kinds whose covariance (shape) matrix is drawn from a Wishart distribution when the BlockMDP is made.
CORRELATED_NOISE_KINDS = ("correlated_gaussian", "correlated_student_t")
#: Each kind's parameters and their defaults (benchmark.md §6; ``student_t``'s ``scale`` is ours, see above).
NOISE_DEFAULTS: dict[str, dict[str, float]] = {
    "gaussian": {"scale": 0.1},
    "correlated_gaussian": {"scale": 0.1},
    "student_t": {"scale": 1.0, "df": 3.0},
    "correlated_student_t": {"scale": 0.1, "df": 1.0},
}


def check_noise_kind(noise: str | None) -> str | None:
    """``noise`` if it is ``None`` or a known kind; otherwise a ``ValueError`` listing the closest names."""
    if noise is None or noise in NOISE_KINDS:
        return noise
    raise ValueError(f"unknown noise {noise!r}{did_you_mean(noise, NOISE_KINDS)} "
                     f"Known: None, {', '.join(map(repr, NOISE_KINDS))}")


def noise_parameters(noise: str | None, params: dict[str, Any]) -> dict[str, float]:
    """The validated parameters of ``noise`` (defaults filled in): ``scale > 0`` and ``df > 0``, both finite.

    Raises ``ValueError`` for a parameter the kind does not take (naming the ones it takes) or out of range.
    """
    if noise is None:
        if params:
            raise ValueError(f"noise parameters {sorted(params)} were given without a noise kind (noise=None)")
        return {}
    allowed = NOISE_DEFAULTS[noise]
    for name in params:
        if name not in allowed:
            raise ValueError(f"noise {noise!r} has no parameter {name!r}{did_you_mean(name, allowed)} "
                             f"It takes: {', '.join(allowed)}")
    out = {}
    for name, default in allowed.items():
        value = params.get(name, default)
        try:
            if isinstance(value, bool):
                raise TypeError
            v = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{name} of noise {noise!r} must be a positive finite number; got {value!r}") from None
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} of noise {noise!r} must be a positive finite number; got {v}")
        out[name] = v
    return out


def wishart_cholesky(key: jax.Array, dim: int, df: float, scale: float | jax.Array, dtype: Any = jnp.float32) -> jax.Array:
    """The lower Cholesky factor ``L`` of one draw ``W = L L^T ~ Wishart(df, scale I_dim)`` (requires ``df > dim - 1``).

    Bartlett's decomposition (Bartlett 1933; e.g. Anderson, *An Introduction to Multivariate Statistical Analysis*,
    §7.2): ``W = (sqrt(scale) A)(sqrt(scale) A)^T`` with ``A`` lower triangular, ``A_ii = sqrt(c_i)``,
    ``c_i ~ chi^2(df - i)`` (``i = 0 .. dim-1``), and ``A_ij ~ N(0, 1)`` for ``i > j``, all independent. Since
    ``sqrt(scale) A`` is lower triangular with a positive diagonal, it *is* the Cholesky factor of ``W``.
    """
    if not df > dim - 1:
        raise ValueError(f"the Wishart degrees of freedom must exceed dim - 1 = {dim - 1}; got {df}")
    k_diag, k_lower = jax.random.split(key)
    c = jax.random.chisquare(k_diag, jnp.asarray(df, dtype) - jnp.arange(dim, dtype=dtype), (dim,), dtype)
    z = jax.random.normal(k_lower, (dim, dim), dtype)
    A = jnp.tril(z, -1) + jnp.diag(jnp.sqrt(c))
    return jnp.sqrt(jnp.asarray(scale, dtype)) * A


def sample_noise(
    key: jax.Array,
    noise: str,
    shape: tuple[int, ...],
    scale: jax.Array,
    df: jax.Array,
    chol: jax.Array | None,
    dtype: Any = jnp.float32,
) -> jax.Array:
    """One draw of noise kind ``noise`` (static) with the observation's ``shape`` (see the module docstring).

    ``scale`` and ``df`` are the kind's parameters (traced scalars; ``df`` unused by the Gaussian kinds), ``chol`` the
    ``[d, d]`` Cholesky factor of the Wishart draw for the correlated kinds (``d = prod(shape)``).
    """
    if noise == "gaussian":
        return scale * jax.random.normal(key, shape, dtype)
    if noise == "student_t":
        return scale * jax.random.t(key, df, shape, dtype)
    if noise not in CORRELATED_NOISE_KINDS:
        raise ValueError(f"unknown noise {noise!r}")
    d = math.prod(shape)
    k_normal, k_chi2 = jax.random.split(key)
    e = chol @ jax.random.normal(k_normal, (d,), dtype)
    if noise == "correlated_student_t":
        e = e * jax.lax.rsqrt(jax.random.chisquare(k_chi2, df, (), dtype) / df)
    return e.reshape(shape)
