"""Emission noise (paper App. A.2; benchmark.md §6) and the Wishart draw of the correlated kinds.

Every statistical check compares a statistic whose exact distribution under a correct sampler is known (a chi-square
sum of squared Gaussians, a normal mean, a binomial count of samples below an exact quantile) with that
distribution's two-sided ``ALPHA = 1e-8`` quantiles, so each check fails a correct sampler with probability at most
``1e-8``; a test's false-failure probability is at most its number of checks times ``1e-8`` (stated per test, all
below ``1e-6``). The bounds come from scipy's exact quantile functions; no normal approximation is involved.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import jaxmdp
import stat_checks
from stat_checks import key
from jaxmdp.blockmdp.noise import NOISE_DEFAULTS, check_noise_kind, noise_parameters, sample_noise, wishart_cholesky

ALPHA = 1e-8


def Checks() -> stat_checks.Checks:  # noqa: N802 - the checks of this file, at ALPHA
    return stat_checks.Checks(ALPHA)


def directions(d: int, rng: np.random.Generator) -> list[np.ndarray]:
    """Unit vectors that pin down a symmetric matrix through ``u^T M u``: the axes, ``(e_i + e_j)/sqrt 2`` for
    ``i < j`` (polarisation gives every off-diagonal entry), and two random directions."""
    eye = np.eye(d)
    out = list(eye) + [(eye[i] + eye[j]) / np.sqrt(2) for i in range(d) for j in range(i + 1, d)]
    for _ in range(2):
        u = rng.standard_normal(d)
        out.append(u / np.linalg.norm(u))
    return out


@functools.partial(jax.jit, static_argnames=("noise", "shape", "n"))
def draws(key, noise, shape, scale, df, chol, n):
    keys = jax.random.split(key, n)
    return jax.vmap(lambda k: sample_noise(k, noise, shape, scale, df, chol))(keys)


@functools.partial(jax.jit, static_argnames=("d", "df", "s", "M"))
def wishart_draws(key, d, df, s, M):
    return jax.vmap(lambda k: wishart_cholesky(k, d, df, s))(jax.random.split(key, M))


# ---------------------------------------------------------------------------------------------------------------
# Wishart
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.statistical(p=1.2e-7)
@pytest.mark.parametrize("df", [4.0, 6.5])
def test_wishart_quadratic_forms_are_chi_square(df):
    # W ~ Wishart(df, s I) iff u^T W u ~ s chi2(df) for every unit u (jointly Wishart aside); summed over M
    # independent draws, sum_m u^T W_m u / s ~ chi2(M df) exactly. In particular E[W] = df s I (the axes give the
    # diagonal, the (e_i + e_j)/sqrt 2 forms the off-diagonal entries by polarisation).
    # 12 checks: false-failure probability <= 1.2e-7.
    d, s, M = 4, 0.3, 20_000
    L = np.asarray(wishart_draws(key(1), d, df, s, M), np.float64)
    assert np.all(np.triu(L, 1) == 0) and np.all(np.diagonal(L, axis1=1, axis2=2) > 0)
    W = L @ np.swapaxes(L, 1, 2)
    checks = Checks()
    for u in directions(d, stat_checks.rng(0)):
        checks.chi2(np.einsum("i,mij,j->", u, W, u) / s, M * df, f"u = {np.round(u, 3)}")
    mean = W.mean(0)
    np.testing.assert_allclose(mean, df * s * np.eye(d), atol=0.05 * df * s)  # implied by the checks above
    assert checks.false_failure_bound() < 1e-6


def test_wishart_rejects_too_few_degrees_of_freedom():
    with pytest.raises(ValueError, match="must exceed dim - 1 = 3"):
        wishart_cholesky(jax.random.key(0), 4, 3.0, 0.1)


def test_wishart_is_reproducible():
    a = wishart_cholesky(jax.random.key(3), 5, 5, 0.1)
    np.testing.assert_array_equal(a, wishart_cholesky(jax.random.key(3), 5, 5, 0.1))
    assert not np.allclose(a, wishart_cholesky(jax.random.key(4), 5, 5, 0.1))


# ---------------------------------------------------------------------------------------------------------------
# The four kinds
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.statistical(p=3e-7)
def test_gaussian_mean_covariance_and_tails():
    # Each component ~ N(0, s^2) independently: mean exact normal; sum of (u^T x)^2 / s^2 ~ chi2(N) for the axes and
    # pairs (zero covariance); |x| > 4 s counted over all values ~ Binomial(6N, 2 Phi(-4)).
    # 6 + 23 + 1 = 30 checks: false-failure probability <= 3e-7.
    N, s, shape = 100_000, 0.3, (2, 3)
    x = np.asarray(draws(key(2), "gaussian", shape, s, 0.0, None, N), np.float64)
    assert x.shape == (N, *shape)
    x = x.reshape(N, -1)
    checks = Checks()
    for i in range(6):
        checks.normal(x[:, i].sum() / (s * np.sqrt(N)), f"mean of component {i}")
    for u in directions(6, stat_checks.rng(1)):
        checks.chi2(np.sum((x @ u) ** 2) / s**2, N, f"variance along {np.round(u, 3)}")
    checks.binomial(int(np.sum(np.abs(x) > 4 * s)), x.size, 2 * stats.norm.sf(4.0), "tail beyond 4 scale")
    assert checks.false_failure_bound() < 1e-6


@pytest.mark.statistical(p=2.4e-7)
@pytest.mark.parametrize("df, s", [(3.0, 1.0), (5.0, 0.3)])
def test_student_t_is_iid_per_component(df, s):
    # x_i / s ~ t(df): counts below exact quantiles (median and far tails included) are Binomial(N, p). Independent
    # components: P(x_i > 0, x_j > 0) = 1/4 (the reference's one shared scalar would give 1/2).
    # 3 components x 7 quantiles + 3 pairs = 24 checks: false-failure probability <= 2.4e-7.
    N = 200_000
    x = np.asarray(draws(key(3), "student_t", (3,), s, df, None, N), np.float64)
    checks = Checks()
    for p in (1e-3, 0.02, 0.25, 0.5, 0.75, 0.98, 0.999):
        q = s * stats.t.ppf(p, df)
        for i in range(3):
            checks.binomial(int(np.sum(x[:, i] <= q)), N, p, f"component {i} below its {p} quantile")
    for i, j in ((0, 1), (0, 2), (1, 2)):
        checks.binomial(int(np.sum((x[:, i] > 0) & (x[:, j] > 0))), N, 0.25, f"components {i}, {j} both positive")
    assert checks.false_failure_bound() < 1e-6


@pytest.mark.statistical(p=2.4e-7)
def test_correlated_gaussian_has_the_wishart_covariance():
    # e ~ N(0, W): u^T e ~ N(0, u^T W u) exactly, so sum (u^T e)^2 / (u^T W u) ~ chi2(N) for every direction, and
    # the mean of u^T e is N(0, u^T W u / N). 12 + 12 = 24 checks: false-failure probability <= 2.4e-7.
    N, shape = 100_000, (2, 2)
    chol = wishart_cholesky(key(5), 4, 4, 0.1)
    W = np.asarray(chol, np.float64) @ np.asarray(chol, np.float64).T
    e = np.asarray(draws(key(6), "correlated_gaussian", shape, 0.1, 0.0, chol, N), np.float64)
    assert e.shape == (N, *shape)
    e = e.reshape(N, 4)
    checks = Checks()
    for u in directions(4, stat_checks.rng(2)):
        var = u @ W @ u
        checks.chi2(np.sum((e @ u) ** 2) / var, N, f"variance along {np.round(u, 3)}")
        checks.normal((e @ u).sum() / np.sqrt(N * var), f"mean along {np.round(u, 3)}")
    assert checks.false_failure_bound() < 1e-6


@pytest.mark.statistical(p=5.3e-7)
@pytest.mark.parametrize("df", [1.0, 4.0])
def test_correlated_student_t_is_multivariate_t(df):
    # e = L z / sqrt(u / df): along any direction, (u^T e) / sqrt(u^T W u) ~ t(df) exactly (counts below quantiles
    # are binomial); e^T W^{-1} e / d ~ F(d, df) exactly, which fails if each component had its own chi-square.
    # 10 directions x 5 quantiles + 3 = 53 checks: false-failure probability <= 5.3e-7.
    N, d = 100_000, 3
    chol = wishart_cholesky(key(7), d, d, 0.1)
    L = np.asarray(chol, np.float64)
    W = L @ L.T
    e = np.asarray(draws(key(8), "correlated_student_t", (d,), 0.1, df, chol, N), np.float64)
    checks = Checks()
    for u in directions(d, stat_checks.rng(3)) + directions(d, stat_checks.rng(4))[-2:]:
        t = (e @ u) / np.sqrt(u @ W @ u)
        for p in (0.01, 0.25, 0.5, 0.75, 0.99):
            checks.binomial(int(np.sum(t <= stats.t.ppf(p, df))), N, p, f"direction {np.round(u, 3)}, quantile {p}")
    z = np.linalg.solve(L, e.T)
    f = np.sum(z**2, axis=0) / d
    for p in (0.01, 0.5, 0.99):
        checks.binomial(int(np.sum(f <= stats.f.ppf(p, d, df))), N, p, f"F({d}, {df}) quantile {p}")
    assert checks.false_failure_bound() < 1e-6


def test_draws_are_reproducible_and_keep_the_dtype():
    for noise in jaxmdp.NOISE_KINDS:
        chol = wishart_cholesky(jax.random.key(0), 6, 6, 0.1) if noise.startswith("correlated") else None
        a = sample_noise(jax.random.key(1), noise, (2, 3), jnp.float32(0.1), jnp.float32(3.0), chol)
        np.testing.assert_array_equal(a, sample_noise(jax.random.key(1), noise, (2, 3), 0.1, 3.0, chol))
        assert a.shape == (2, 3) and a.dtype == jnp.float32 and np.all(np.isfinite(a))


# ---------------------------------------------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------------------------------------------


def test_defaults_of_the_spec():
    # benchmark.md §6: Gaussian scale 0.1; Wishart scale 0.1 for both correlated kinds; Student-t df 3 (unit scale, as
    # the reference's standard_t); correlated Student-t df 1 (scipy's multivariate_t default).
    assert NOISE_DEFAULTS == {
        "gaussian": {"scale": 0.1},
        "correlated_gaussian": {"scale": 0.1},
        "student_t": {"scale": 1.0, "df": 3.0},
        "correlated_student_t": {"scale": 0.1, "df": 1.0},
    }
    assert noise_parameters("student_t", {"df": 5}) == {"scale": 1.0, "df": 5.0}


@pytest.mark.parametrize("value", [0, -0.1, float("inf"), float("nan"), True, "big", None])
@pytest.mark.parametrize("name", ["scale", "df"])
def test_out_of_range_parameters_are_rejected(name, value):
    with pytest.raises(ValueError, match=f"{name} of noise 'correlated_student_t' must be a positive finite number"):
        noise_parameters("correlated_student_t", {name: value})


def test_parameters_a_kind_does_not_take_are_rejected():
    with pytest.raises(ValueError, match="noise 'gaussian' has no parameter 'df' It takes: scale"):
        noise_parameters("gaussian", {"df": 3})
    with pytest.raises(ValueError, match="no parameter 'scal'; did you mean 'scale'"):
        noise_parameters("student_t", {"scal": 3})
    with pytest.raises(ValueError, match=r"noise parameters \['scale'\] were given without a noise kind"):
        noise_parameters(None, {"scale": 3})


def test_unknown_kinds_list_the_closest_names():
    with pytest.raises(ValueError, match="unknown noise 'gausian'; did you mean 'gaussian'"):
        check_noise_kind("gausian")
    with pytest.raises(ValueError, match="did you mean 'correlated_student_t'"):
        check_noise_kind("correlated_studentt")
