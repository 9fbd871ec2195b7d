"""Conjugate posteriors: updates against the closed forms, samples against their exact distributions."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from stat_checks import Checks, key
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
# Statistical checks (tests/stat_checks.py) fail a correct sampler with probability <= 1e-7 each (exact distributions
# of the statistics); each test states its total.
log_gamma_sample_jit = jax.jit(log_gamma_sample)
batched_log_gamma_sample = jax.jit(jax.vmap(log_gamma_sample, (0, None)))
normal_gamma_draws = jax.jit(lambda k, post: jax.vmap(normal_gamma_sample, (0, None))(jax.random.split(k, N_DRAWS),
                                                                                         post))
dirichlet_draws = jax.jit(lambda k, a: jax.vmap(dirichlet_sample, (0, None))(jax.random.split(k, N_DRAWS), a))


@pytest.mark.statistical(p=2e-7)
@pytest.mark.parametrize("alpha", [0.04, 0.5, 1.0, 2.5, 30.0])
def test_log_gamma_sample_is_exact(alpha):
    # Kolmogorov-Smirnov against scipy's Gamma(alpha) CDF, on log g (P(log g <= x) = F(e^x)), plus the sum of g,
    # exactly Gamma(N alpha). 2 checks: false-failure probability <= 2e-7.
    draws = np.asarray(log_gamma_sample_jit(key(0), jnp.full((N_DRAWS,), alpha)), np.float64)
    assert np.all(np.isfinite(draws))
    checks = Checks()
    checks.ks(draws, lambda x: stats.gamma(alpha).cdf(np.exp(x)), "log g")
    checks.gamma_sum(np.exp(draws).sum(), N_DRAWS * alpha, "sum of g")


@pytest.mark.statistical(p=3e-7)
def test_log_gamma_sample_mixed_shapes_and_batching():
    # One call with many shapes equals the same distribution per entry (3 KS checks: false-failure probability
    # <= 3e-7); under vmap each member is its own draw.
    alpha = jnp.tile(jnp.array([0.3, 1.0, 7.0]), N_DRAWS // 3)
    sample = log_gamma_sample_jit
    draws = np.exp(np.asarray(sample(key(1), alpha), np.float64)).reshape(-1, 3)
    checks = Checks()
    for j, a in enumerate((0.3, 1.0, 7.0)):
        checks.ks(draws[:, j], stats.gamma(a).cdf, f"shape {a}")
    keys = jax.random.split(jax.random.key(2), 3)
    batched = batched_log_gamma_sample(keys, jnp.array([0.5, 2.0]))
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


@pytest.mark.statistical(p=8e-7)
def test_normal_gamma_sample_is_student_t():
    # Marginally, m ~ Student-t(2 alpha) with location mu and scale sqrt(beta / (lam alpha)): KS, and the counts
    # below exact quantiles (the tails check the scale, the median the location; the former variance check failed
    # about 9.5% of fresh keys). 1 + 7 checks: false-failure probability <= 8e-7.
    mu, lam, alpha, beta = 0.3, 2.0, 3.5, 2.0
    post = normal_gamma_prior((), mu, lam, alpha / beta, 2 * alpha)
    draws = np.asarray(normal_gamma_draws(key(1), post), np.float64)
    marginal = stats.t(df=2 * alpha, loc=mu, scale=np.sqrt(beta / (lam * alpha)))
    checks = Checks()
    checks.ks(draws, marginal.cdf, "m")
    checks.below_quantiles(draws, marginal.ppf, (0.001, 0.02, 0.2, 0.5, 0.8, 0.98, 0.999), "m")


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


@pytest.mark.statistical(p=1.1e-6)
def test_dirichlet_sample_marginals_are_beta():
    # Component i's marginal is Beta(alpha_i, alpha_0 - alpha_i): mean and variance by Bernstein's inequality (bounded
    # in [0, 1]) for the four with mass, KS for three (the fourth, alpha = 0.04, piles up below float32's resolution).
    # 8 + 3 = 11 checks at 1e-7 each: false-failure probability <= 1.1e-6 for the test, 1e-7 per assertion.
    alpha = jnp.array([0.3, 1.0, 2.5, 0.04, 0.0])
    a0 = float(alpha.sum())
    draws = np.asarray(dirichlet_draws(key(3), alpha), np.float64)
    np.testing.assert_allclose(draws.sum(-1), 1.0, atol=1e-6)
    assert np.all(draws[:, 4] == 0.0)  # no concentration, no mass (padded state)
    a = np.asarray(alpha, np.float64)
    checks = Checks()
    for i in range(4):
        checks.bounded_moments(draws[:, i], stats.beta(a[i], a0 - a[i]), 0.0, 1.0, f"component {i}")
    for i in (0, 1, 2):
        checks.ks(draws[:, i], stats.beta(a[i], a0 - a[i]).cdf, f"component {i}")


@pytest.mark.parametrize("S", [25, 400])
def test_dirichlet_sample_small_concentrations_stay_normalised(S):
    # The default prior 1/S: most gamma variates underflow in float32, the log-space draw does not.
    alpha = jnp.full((8, S), 1.0 / S)
    draws = jax.jit(dirichlet_sample)(jax.random.key(4), alpha)
    assert bool(jnp.all(jnp.isfinite(draws)))
    np.testing.assert_allclose(draws.sum(-1), 1.0, atol=1e-5)
