"""Reward sampling: the bulk-candidate Beta / log-Gamma sampler against the exact distributions (scipy), including
tiny shapes and the fallback rounds, and the environment's point-mass fast path."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import jaxmdp
from jaxmdp.sampling.beta_sampling import sample_beta, sample_log_gamma
from stat_checks import Checks, key

N = 50_000
QUANTILES = (1e-3, 0.02, 0.25, 0.5, 0.75, 0.98, 0.999)


# Shapes are traced arguments so that every parameter value shares one compiled program.
@functools.partial(jax.jit, static_argnames="candidates")
def log_gammas(k, a, candidates):
    return jax.vmap(lambda k: sample_log_gamma(k, a, candidates=candidates))(jax.random.split(k, N))


@functools.partial(jax.jit, static_argnames="candidates")
def betas(k, a, b, candidates):
    return jax.vmap(lambda k: sample_beta(k, a, b, candidates=candidates))(jax.random.split(k, N))


@pytest.mark.statistical(p=8e-7)
@pytest.mark.parametrize("candidates", [4, 1])  # 1 candidate: ~5% of draws go through the fallback loop
@pytest.mark.parametrize("a", [0.01, 0.11, 0.5, 1.0, 2.4, 50.0])
def test_log_gamma_is_exact(a, candidates):
    # P(ln G <= y) = P(G <= e^y): KS against scipy's log-Gamma CDF (no underflow for tiny shapes) and the counts below
    # 7 exact quantiles (Binomial). 8 checks: false-failure probability <= 8e-7 (tests/stat_checks.py).
    y = np.asarray(log_gammas(key(2024), jnp.float32(a), candidates), np.float64)
    assert np.all(np.isfinite(y))
    checks = Checks()
    checks.ks(y, stats.loggamma(a).cdf, "ln G")
    checks.below_quantiles(y, stats.loggamma(a).ppf, QUANTILES, "ln G")


@pytest.mark.statistical(p=1e-6)
@pytest.mark.parametrize("candidates", [4, 1])
@pytest.mark.parametrize("a, b", [(2.4, 24.0), (0.5, 0.5), (12.4, 1249.0), (1.0, 1.0), (80.0, 1.0), (0.3, 3.0),
                                  (1.0, 0.11)])
def test_beta_is_exact(a, b, candidates):
    # KS where float32 resolves the distribution, counts below the exact quantiles that it resolves, mean and variance
    # by Bernstein (bounded in [0, 1]). At most 1 + 7 + 2 = 10 checks: false-failure probability <= 1e-6.
    x = np.asarray(betas(key(2025), jnp.float32(a), jnp.float32(b), candidates), np.float64)
    assert np.all((x >= 0) & (x <= 1))
    ref = stats.beta(a, b)
    checks = Checks()
    if b >= 0.5:  # mass piled up just below 1 is rounded to 1.0 in float32, which a KS test would flag
        checks.ks(x, ref.cdf, f"Beta({a}, {b})")
    # Quantiles float32 resolves: below 1 - 1e-6 (6e-8 is float32's spacing below 1) and above 1e-30.
    probs = [p for p in QUANTILES if 1e-30 < ref.ppf(p) < 1 - 1e-6]
    checks.below_quantiles(x, ref.ppf, probs, f"Beta({a}, {b})")
    checks.bounded_moments(x, ref, 0.0, 1.0, f"Beta({a}, {b})")


@pytest.mark.statistical(p=3e-7)
def test_tiny_shapes_stay_finite():
    # Colosseum's RiverSwim optimal reward is Beta(0.01, 0.11): most of the mass sits within 1e-30 of 0 or 1.
    # Mean by Bernstein (bounded), the count below 1/2 exactly Binomial(N, F(1/2)). 3 checks: <= 3e-7.
    x = np.asarray(betas(key(2026), jnp.float32(0.01), jnp.float32(0.11), 4), np.float64)
    assert np.all(np.isfinite(x))
    ref, checks = stats.beta(0.01, 0.11), Checks()
    checks.bounded_moments(x, ref, 0.0, 1.0, "Beta(0.01, 0.11)")
    checks.binomial(int(np.sum(x <= 0.5)), N, ref.cdf(0.5), "Beta(0.01, 0.11) below 1/2")


def test_deterministic_reward_flag_skips_only_the_draw():
    # On an MDP with point-mass rewards, the static flag off gives the same trajectory as forcing the draw path.
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4, randomize_actions=False, p_lazy=0.3)
    keys = jax.random.split(jax.random.key(5), 50)
    state = jaxmdp.reset(keys[0], m)[1]
    assert not m.stochastic_rewards
    fast = jax.jit(lambda k, s, a: jaxmdp.step(k, s, a, m))
    slow = jax.jit(lambda k, s, a: jaxmdp.step(k, s, a, m.replace(stochastic_rewards=True)))
    s1 = s2 = state
    for i, k in enumerate(keys):
        o1, s1, r1, t1, _, _ = fast(k, s1, i % 2)
        o2, s2, r2, t2, _, _ = slow(k, s2, i % 2)
        assert (int(o1), float(r1), bool(t1)) == (int(o2), float(r2), bool(t2))
