"""Conjugate posteriors: updates against the closed forms, samples against their exact distributions."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from agents.posteriors import (
    dirichlet_concentration,
    log_gamma_sample,
    dirichlet_mean,
    dirichlet_sample,
    normal_gamma_mean,
    normal_gamma_observe,
    normal_gamma_prior,
    normal_gamma_sample,
)

N_DRAWS = 20_000


@pytest.mark.parametrize("alpha", [0.04, 0.5, 1.0, 2.5, 30.0])
def test_log_gamma_sample_is_exact(alpha):
    # Kolmogorov-Smirnov against scipy's Gamma(alpha) CDF, on log g (P(log g <= x) = F(e^x)), plus the mean of g.
    draws = np.asarray(jax.jit(log_gamma_sample)(jax.random.key(0), jnp.full((N_DRAWS,), alpha)), np.float64)
    assert np.all(np.isfinite(draws))
    assert stats.kstest(draws, lambda x: stats.gamma(alpha).cdf(np.exp(x))).pvalue > 1e-3
    g = np.exp(draws)
    assert abs(g.mean() - alpha) < 5 * np.sqrt(alpha / N_DRAWS)


def test_log_gamma_sample_mixed_shapes_and_batching():
    # One call with many shapes equals the same distribution per entry; under vmap each member is its own draw.
    alpha = jnp.tile(jnp.array([0.3, 1.0, 7.0]), N_DRAWS // 3)
    sample = jax.jit(log_gamma_sample)
    draws = np.exp(np.asarray(sample(jax.random.key(1), alpha), np.float64)).reshape(-1, 3)
    for j, a in enumerate((0.3, 1.0, 7.0)):
        assert stats.kstest(draws[:, j], stats.gamma(a).cdf).pvalue > 1e-3, a
    keys = jax.random.split(jax.random.key(2), 3)
    batched = jax.jit(jax.vmap(log_gamma_sample, (0, None)))(keys, jnp.array([0.5, 2.0]))
    np.testing.assert_array_equal(batched[1], sample(keys[1], jnp.array([0.5, 2.0])))


def test_normal_gamma_prior_parameterisation():
    # [mu0, n_mu, tau0, n_tau] = [0.4, 2, 4, 3] -> (mu, lam, alpha, beta) = (0.4, 2, 1.5, 1.5 / 4).
    post = normal_gamma_prior((2, 3), 0.4, 2.0, 4.0, 3.0)
    np.testing.assert_allclose(post.mu, 0.4)
    np.testing.assert_allclose(post.lam, 2.0)
    np.testing.assert_allclose(post.alpha, 1.5)
    np.testing.assert_allclose(post.beta, 0.375)


def test_normal_gamma_sequential_updates_equal_batch_closed_form():
    rng = np.random.default_rng(0)
    mu0, lam0, a0, b0 = 0.3, 1.5, 0.5, 0.7
    post = normal_gamma_prior((2, 2), mu0, lam0, a0 / b0, 2 * a0)  # tau0 = alpha / beta, n_tau = 2 alpha
    xs = rng.uniform(0, 1, size=17)
    observe = jax.jit(normal_gamma_observe)
    for x in xs:
        post = observe(post, (1, 0), x)
    # Batch conjugate update (Murphy 2007, eq. 85-89).
    n, xbar = len(xs), xs.mean()
    ss = np.sum((xs - xbar) ** 2)
    lam = lam0 + n
    mu = (lam0 * mu0 + n * xbar) / lam
    alpha = a0 + n / 2
    beta = b0 + 0.5 * (ss + lam0 * n * (xbar - mu0) ** 2 / lam)
    np.testing.assert_allclose(
        [post.mu[1, 0], post.lam[1, 0], post.alpha[1, 0], post.beta[1, 0]], [mu, lam, alpha, beta], rtol=2e-6
    )
    # The other pairs are untouched.
    np.testing.assert_allclose(post.mu[0], mu0)
    np.testing.assert_allclose(post.beta[1, 1], b0)
    np.testing.assert_allclose(normal_gamma_mean(post)[1, 0], mu, rtol=2e-6)


def test_normal_gamma_sample_is_student_t():
    # Marginally, m ~ Student-t(2 alpha) with location mu and scale sqrt(beta / (lam alpha)).
    mu, lam, alpha, beta = 0.3, 2.0, 3.5, 2.0
    post = normal_gamma_prior((), mu, lam, alpha / beta, 2 * alpha)
    keys = jax.random.split(jax.random.key(1), N_DRAWS)
    draws = np.asarray(jax.jit(jax.vmap(normal_gamma_sample, (0, None)))(keys, post), np.float64)
    scale = np.sqrt(beta / (lam * alpha))
    assert stats.kstest(draws, stats.t(df=2 * alpha, loc=mu, scale=scale).cdf).pvalue > 1e-3
    # Moments: mean mu, variance beta / (lam (alpha - 1)); tolerances are 5 standard errors.
    var = beta / (lam * (alpha - 1))
    assert abs(draws.mean() - mu) < 5 * np.sqrt(var / N_DRAWS)
    assert abs(draws.var() / var - 1) < 0.1


def test_normal_gamma_sample_is_finite_for_tiny_shapes():
    post = normal_gamma_prior((64,), 0.0, 1.0, 1.0, 1e-3)  # alpha = 5e-4: the precision draw underflows
    draws = jax.jit(jax.vmap(normal_gamma_sample, (0, None)))(jax.random.split(jax.random.key(2), 200), post)
    assert bool(jnp.all(jnp.isfinite(draws)))


def test_dirichlet_concentration_and_mean():
    counts = jnp.array([[[3, 0, 1, 0]]], jnp.int32)
    mask = jnp.array([True, True, True, False])
    alpha = dirichlet_concentration(0.5, counts, mask)
    np.testing.assert_allclose(alpha, [[[3.5, 0.5, 1.5, 0.0]]])
    np.testing.assert_allclose(dirichlet_mean(alpha), [[[3.5 / 5.5, 0.5 / 5.5, 1.5 / 5.5, 0.0]]], rtol=1e-6)


def test_dirichlet_sample_marginals_are_beta():
    alpha = jnp.array([0.3, 1.0, 2.5, 0.04, 0.0])
    a0 = float(alpha.sum())
    keys = jax.random.split(jax.random.key(3), N_DRAWS)
    draws = np.asarray(jax.jit(jax.vmap(dirichlet_sample, (0, None)))(keys, alpha), np.float64)
    np.testing.assert_allclose(draws.sum(-1), 1.0, atol=1e-6)
    assert np.all(draws[:, 4] == 0.0)  # no concentration, no mass (padded state)
    a = np.asarray(alpha, np.float64)
    mean = a / a0
    var = a * (a0 - a) / (a0**2 * (a0 + 1))
    for i in range(4):
        assert abs(draws[:, i].mean() - mean[i]) < 5 * np.sqrt(var[i] / N_DRAWS), i
        assert abs(draws[:, i].var() / var[i] - 1) < 0.1, i
    for i in (0, 1, 2):  # the marginal of component i is Beta(alpha_i, alpha_0 - alpha_i)
        assert stats.kstest(draws[:, i], stats.beta(a[i], a0 - a[i]).cdf).pvalue > 1e-3, i


@pytest.mark.parametrize("S", [25, 400])
def test_dirichlet_sample_small_concentrations_stay_normalised(S):
    # The default prior 1/S: most gamma variates underflow in float32, the log-space draw does not.
    alpha = jnp.full((8, S), 1.0 / S)
    draws = jax.jit(dirichlet_sample)(jax.random.key(4), alpha)
    assert bool(jnp.all(jnp.isfinite(draws)))
    np.testing.assert_allclose(draws.sum(-1), 1.0, atol=1e-5)
