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


def orthonormal_pairs(d: int, rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray]]:
    """Pairs of orthonormal directions: two axes, the rotated pair ``(e_0 +- e_1)/sqrt 2``, ``(e_2 +- e_3)/sqrt 2``
    and the first two columns of a random orthogonal matrix."""
    eye = np.eye(d)
    q = np.linalg.qr(rng.standard_normal((d, d)))[0]
    return [(eye[0], eye[1]), ((eye[0] + eye[1]) / np.sqrt(2), (eye[0] - eye[1]) / np.sqrt(2)),
            ((eye[2] + eye[3]) / np.sqrt(2), (eye[2] - eye[3]) / np.sqrt(2)), (q[:, 0], q[:, 1])]


WISHART_PROBS = (0.02, 0.5, 0.98)


def wishart_checks(L: np.ndarray, df: float, s: float, pairs) -> stat_checks.Checks:
    """The distribution of ``W = L L^T`` for i.i.d. draws ``L[m]`` of ``Wishart(df, s I)`` (float64), through facts of
    the Wishart distribution itself, not of the sampler. ``W`` is rotation invariant (its density,
    ``|W|^{(df-d-1)/2} exp(-tr W / 2s)``, is), so for orthonormal ``u, v`` the matrix ``O^T W O`` with
    ``O = [u, v, ...]`` is again ``Wishart(df, s I)`` and Bartlett's decomposition of it gives, exactly and for real
    ``df``: ``q_u = u^T W u / s ~ chi2(df)``, ``q_v`` likewise and independent of ``q_u``, and
    ``r = u^T W v / sqrt(s u^T W u) ~ N(0, 1)`` independent of ``q_u``. Per pair: counts below 3 exact quantiles of
    ``q_u``, ``q_v`` and ``r`` (binomial) and 2 sign-agreement counts (Binomial(M, 1/2)): 11 checks. (The second moments
    follow: Var W_ii = 2 df s^2, Var W_ij = df s^2, entries uncorrelated.)"""
    W = L @ np.swapaxes(L, 1, 2)
    checks = Checks()
    chi2 = stats.chi2(df)
    for u, v in pairs:
        where = f"u = {np.round(u, 3)}, v = {np.round(v, 3)}"
        qu, qv = np.einsum("i,mij,j->m", u, W, u) / s, np.einsum("i,mij,j->m", v, W, v) / s
        r = np.einsum("i,mij,j->m", u, W, v) / np.sqrt(s * s * qu)
        checks.below_quantiles(qu, chi2.ppf, WISHART_PROBS, f"u^T W u / s ~ chi2({df}), {where}")
        checks.below_quantiles(qv, chi2.ppf, WISHART_PROBS, f"v^T W v / s ~ chi2({df}), {where}")
        checks.below_quantiles(r, stats.norm.ppf, WISHART_PROBS, f"u^T W v / sqrt(s u^T W u) ~ N(0, 1), {where}")
        checks.independent_signs(qu, qv, chi2.median(), chi2.median(), f"q_u, q_v independent, {where}")
        checks.independent_signs(r, qu, 0.0, chi2.median(), f"r, q_u independent, {where}")
    return checks


def diagonal(x: np.ndarray) -> np.ndarray:
    """``[M, d]`` -> ``[M, d, d]`` diagonal matrices."""
    return x[:, :, None] * np.eye(x.shape[1])


def no_off_diagonal_normals(rng: np.random.Generator, M: int, d: int, df: float, s: float) -> np.ndarray:
    """A wrong sampler: Bartlett's factor without its normals below the diagonal (``W_ii ~ s chi2(df - i)``)."""
    return np.sqrt(s) * diagonal(np.sqrt(rng.chisquare(df - np.arange(d), (M, d))))


def diagonal_chi_square(rng: np.random.Generator, M: int, d: int, df: float, s: float) -> np.ndarray:
    """A wrong sampler with the right mean ``df s I`` and the right law of every diagonal entry: ``W`` diagonal,
    ``W_ii ~ s chi2(df)`` i.i.d. (every ``u^T W u`` has mean ``df s``; their sums over draws pass a chi-square test of
    the mean)."""
    return np.sqrt(s) * diagonal(np.sqrt(rng.chisquare(df, (M, d))))


@pytest.mark.statistical(p=4.4e-7)
@pytest.mark.parametrize("df", [4.0, 6.5])
def test_wishart_draws_have_the_wishart_distribution(df):
    # wishart_checks: 4 pairs x 11 = 44 checks: false-failure probability <= 4.4e-7. The two wrong samplers fail them
    # by far (the diagonal one: r = 0 for the axes, q_u = (c_0 + c_1) / 2 with half the variance on the rotated pair;
    # counts hundreds of standard deviations outside their bands), so they fail with probability ~1.
    d, s, M = 4, 0.3, 20_000
    L = np.asarray(wishart_draws(key(1), d, df, s, M), np.float64)
    assert np.all(np.triu(L, 1) == 0) and np.all(np.diagonal(L, axis1=1, axis2=2) > 0)
    pairs = orthonormal_pairs(d, stat_checks.rng(0))
    assert wishart_checks(L, df, s, pairs).false_failure_bound() < 1e-6
    np.testing.assert_allclose((L @ np.swapaxes(L, 1, 2)).mean(0), df * s * np.eye(d), atol=0.05 * df * s)
    rng = np.random.default_rng(0)
    for wrong in (no_off_diagonal_normals, diagonal_chi_square):
        with pytest.raises(AssertionError):
            wishart_checks(wrong(rng, M, d, df, s), df, s, pairs)


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


T_PROBS = (1e-3, 0.02, 0.25, 0.5, 0.75, 0.98, 0.999)
PAIRS = ((0, 1), (0, 2), (1, 2))


def student_t_checks(x: np.ndarray, df: float, s: float) -> stat_checks.Checks:
    """i.i.d. components ``x[:, i] / s ~ t(df)`` of i.i.d. draws ``x[n]`` (float64, 3 components).

    Each component: counts below 7 exact quantiles (median and far tails included) are Binomial(N, p). Each pair
    ``i, j``: independent components have independent signs (``P(x_i > 0, x_j > 0) = 1/4``) and independent magnitudes:
    ``|x_i|`` and ``|x_j|`` on the same side of their median ``s t_{0.75}`` for half the draws (Binomial(N, 1/2)), and
    both beyond ``s t_{0.995}`` for a fraction ``0.01^2`` (Binomial(N, 1e-4)). The magnitudes are what tells i.i.d.
    components from a shared denominator ``z_i / sqrt(u / df)``, whose marginals are exactly ``t(df)`` and whose signs
    are independent too. 3 x 7 + 3 x 3 = 30 checks."""
    checks = Checks()
    for p in T_PROBS:
        q = s * stats.t.ppf(p, df)
        for i in range(3):
            checks.binomial(int(np.sum(x[:, i] <= q)), x.shape[0], p, f"component {i} below its {p} quantile")
    median, tail = s * stats.t.ppf(0.75, df), s * stats.t.isf(0.005, df)
    for i, j in PAIRS:
        both_positive = int(np.sum((x[:, i] > 0) & (x[:, j] > 0)))
        checks.binomial(both_positive, x.shape[0], 0.25, f"components {i}, {j} both positive")
        checks.independent_signs(np.abs(x[:, i]), np.abs(x[:, j]), median, median, f"|x_{i}|, |x_{j}|")
        checks.binomial(int(np.sum((np.abs(x[:, i]) > tail) & (np.abs(x[:, j]) > tail))), x.shape[0], 1e-4,
                        f"components {i}, {j} both beyond their 0.995 quantile in magnitude")
    return checks


@pytest.mark.statistical(p=3e-7)
@pytest.mark.parametrize("df, s", [(3.0, 1.0), (5.0, 0.3)])
def test_student_t_is_iid_per_component(df, s):
    # student_t_checks: 30 checks, false-failure probability <= 3e-7. Two wrong samplers with exact t(df) marginals
    # must fail: one shared denominator (the magnitudes agree about their median for ~56% (df 3) / 54% (df 5) of the
    # draws against a band of 50 +- 0.7%, and both are in the far tail ~20 times as often), and the reference's one
    # scalar for every component (signs agree always).
    N = 200_000
    x = np.asarray(draws(key(3), "student_t", (3,), s, df, None, N), np.float64)
    assert student_t_checks(x, df, s).false_failure_bound() < 1e-6
    rng = np.random.default_rng(0)
    shared_denominator = s * rng.standard_normal((N, 3)) / np.sqrt(rng.chisquare(df, (N, 1)) / df)
    one_scalar = np.repeat(s * rng.standard_t(df, (N, 1)), 3, axis=1)
    for wrong in (shared_denominator, one_scalar):
        with pytest.raises(AssertionError):
            student_t_checks(wrong, df, s)


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


@pytest.mark.nightly  # by default: each kind's distribution test
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
