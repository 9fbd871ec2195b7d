"""Reward sampling: the bulk-candidate Beta / log-Gamma sampler against the exact distributions (scipy), including
tiny shapes and the fallback rounds, and the environment's point-mass fast path."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import special, stats

import jaxmdp
from jaxmdp.sampling.beta_sampling import sample_beta, sample_log_gamma

N = 100_000
KEYS = jax.random.split(jax.random.key(2024), N)


# Shapes are traced arguments so that every parameter value shares one compiled program.
@functools.partial(jax.jit, static_argnames="candidates")
def log_gammas(a, candidates):
    return jax.vmap(lambda k: sample_log_gamma(k, a, candidates=candidates))(KEYS)


@functools.partial(jax.jit, static_argnames="candidates")
def betas(a, b, candidates):
    return jax.vmap(lambda k: sample_beta(k, a, b, candidates=candidates))(KEYS)


@pytest.mark.parametrize("candidates", [4, 1])  # 1 candidate: ~5% of draws go through the fallback loop
@pytest.mark.parametrize("a", [0.01, 0.11, 0.5, 1.0, 2.4, 50.0])
def test_log_gamma_is_exact(a, candidates):
    y = np.asarray(log_gammas(jnp.float32(a), candidates), np.float64)
    assert np.all(np.isfinite(y))
    # P(ln G <= y) = P(G <= e^y): compare with the Gamma CDF in log space (no underflow for tiny shapes).
    p = stats.kstest(y, lambda t: stats.gamma.cdf(np.exp(t), a)).pvalue
    assert p > 1e-3, p
    # E[ln G] = digamma(a), Var[ln G] = trigamma(a): a sharper check of the location (6 standard errors).
    assert abs(y.mean() - special.digamma(a)) < 6 * np.sqrt(special.polygamma(1, a) / N)


@pytest.mark.parametrize("candidates", [4, 1])
@pytest.mark.parametrize("a, b", [(2.4, 24.0), (0.5, 0.5), (12.4, 1249.0), (1.0, 1.0), (80.0, 1.0), (0.3, 3.0),
                                  (1.0, 0.11)])
def test_beta_is_exact(a, b, candidates):
    x = np.asarray(betas(jnp.float32(a), jnp.float32(b), candidates), np.float64)
    assert np.all((x >= 0) & (x <= 1))
    if b >= 0.5:  # mass piled up just below 1 is rounded to 1.0 in float32, which a KS test would flag
        assert stats.kstest(x, stats.beta(a, b).cdf).pvalue > 1e-3
    mean, sd = a / (a + b), stats.beta(a, b).std()
    assert abs(x.mean() - mean) < 6 * sd / np.sqrt(N)
    assert abs(x.std() - sd) < 0.02 * sd


def test_tiny_shapes_stay_finite():
    # Colosseum's RiverSwim optimal reward is Beta(0.01, 0.11): most of the mass sits within 1e-30 of 0 or 1.
    x = np.asarray(betas(jnp.float32(0.01), jnp.float32(0.11), 4))
    assert np.all(np.isfinite(x)) and abs(x.mean() - 0.01 / 0.12) < 6 * stats.beta(0.01, 0.11).std() / np.sqrt(N)
    assert 0.4 < np.mean(x < 0.5) < 0.99


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
