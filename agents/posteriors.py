"""Conjugate posteriors of tabular model-based agents (docs/agents.md §1): Dirichlet transitions, Normal-Gamma rewards.

Every ``(s, a)`` has its own independent posterior; arrays carry the ``[S, A]`` (or ``[S, A, S]``) layout and all
functions are pure, so a batch of agents is a ``vmap`` away.

* **Transitions.** ``P(.|s, a) ~ Dirichlet(alpha[s, a, :])`` with ``alpha = prior * state_mask + N[s, a, :]``
  (counts of observed next states). The prior puts its concentration on every *real* next state and none on padded
  ones, so a padded state is never predicted.
* **Rewards.** Normal with unknown mean and precision, ``x ~ N(m, 1/tau)``, under the conjugate Normal-Gamma prior
  ``tau ~ Gamma(alpha, rate beta)``, ``m | tau ~ N(mu, 1/(lambda tau))``. The reference states its prior as
  ``[mu0, n_mu, tau0, n_tau]`` (prior mean, pseudo-count of the mean, prior precision, pseudo-count of the
  precision), i.e. ``(mu, lambda, alpha, beta) = (mu0, n_mu, n_tau / 2, (n_tau / 2) / tau0)``.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from jaxmdp import struct
from jaxmdp.sampling.beta_sampling import sample_log_gamma

__all__ = [
    "COLOSSEUM_DIRICHLET_OFFSET",
    "LogGammaSampler",
    "log_gamma_sample",
    "dirichlet_concentration",
    "dirichlet_mean",
    "dirichlet_sample",
    "NormalGamma",
    "normal_gamma_prior",
    "normal_gamma_observe",
    "normal_gamma_mean",
    "normal_gamma_sample",
]

# Largest standard deviation a reward sample may have: a Gamma draw of a small shape can underflow towards zero, and
# an infinite reward would turn the zero entries of a kernel into NaNs during planning (0 * inf).
_MAX_LOG_STD = 30.0
#: The reference's Dirichlet draws divide the Gamma variates by ``sum + 1e-5`` (docs/agents.md §1).
COLOSSEUM_DIRICHLET_OFFSET = 1e-5


# ---------------------------------------------------------------------------------------------------------------
# Gamma variates
# ---------------------------------------------------------------------------------------------------------------


#: ``log_gamma(key, alpha) -> log g`` with ``g ~ Gamma(alpha, 1)`` elementwise, in ``alpha``'s dtype.
LogGammaSampler = Callable[[jax.Array, jax.Array], jax.Array]


def log_gamma_sample(key: jax.Array, alpha: jax.Array) -> jax.Array:
    """``log g`` with ``g ~ Gamma(alpha, 1)`` elementwise, for ``alpha > 0`` (any array shape), in ``alpha``'s dtype.

    Marsaglia & Tsang (2000) rejection with boosting for shapes below one, kept in log space so that tiny shapes
    (``1/S`` priors) do not underflow: :func:`jaxmdp.sampling.beta_sampling.sample_log_gamma` (one round over the array,
    the rare rejections compacted). Exact, with a different stream from ``jax.random.loggamma`` and many times faster.
    """
    alpha = jnp.asarray(alpha)
    return sample_log_gamma(key, alpha, dtype=alpha.dtype)


# ---------------------------------------------------------------------------------------------------------------
# Dirichlet transitions
# ---------------------------------------------------------------------------------------------------------------


def dirichlet_concentration(prior: jax.Array, counts: jax.Array, state_mask: jax.Array) -> jax.Array:
    """Posterior concentration ``alpha[s, a, s'] = prior * [s' real] + N[s, a, s']`` (conjugate update)."""
    dtype = jnp.result_type(prior, float)
    return jnp.asarray(prior, dtype) * state_mask.astype(dtype) + counts.astype(dtype)


def dirichlet_mean(alpha: jax.Array) -> jax.Array:
    """Posterior mean ``alpha / sum(alpha)`` along the last axis (the reference's transition "MAP")."""
    return alpha / jnp.sum(alpha, axis=-1, keepdims=True)


def dirichlet_sample(
    key: jax.Array, alpha: jax.Array, log_gamma: LogGammaSampler = log_gamma_sample, *, offset: float = 0.0
) -> jax.Array:
    """One draw ``p ~ Dirichlet(alpha)`` per row of ``alpha[..., S]``; entries with ``alpha == 0`` get probability 0.

    Draws ``log g_i`` with ``g_i ~ Gamma(alpha_i, 1)`` and returns ``softmax(log g)``: normalising in log space keeps
    small concentrations (the default prior is ``1/S``) exact where ``g_i`` itself would underflow to zero, and every
    row sums to one exactly (the reference divides by ``sum + 1e-5``). ``log_gamma`` draws the ``log g_i``
    (default :func:`log_gamma_sample`; ``jax.random.loggamma`` may be passed to compare, docs/performance.md,
    Sampling).
    ``offset > 0`` (static) returns ``g / (sum g + offset)`` instead, still in log space: the reference's rows, which
    sum to less than one (reference mode uses :data:`COLOSSEUM_DIRICHLET_OFFSET`).
    """
    positive = alpha > 0
    log_g = log_gamma(key, jnp.where(positive, alpha, 1.0))
    if not offset:
        return jax.nn.softmax(jnp.where(positive, log_g, -jnp.inf), axis=-1)
    log_g = jnp.where(positive, log_g, -jnp.inf)
    log_z = jnp.logaddexp(jax.nn.logsumexp(log_g, axis=-1, keepdims=True), jnp.log(jnp.asarray(offset, log_g.dtype)))
    return jnp.exp(log_g - log_z)


# ---------------------------------------------------------------------------------------------------------------
# Normal-Gamma rewards
# ---------------------------------------------------------------------------------------------------------------


class NormalGamma(struct.PyTreeNode):
    """Normal-Gamma posterior parameters ``(mu, lam, alpha, beta)``, each of the same shape (usually ``[S, A]``)."""

    mu: jax.Array
    lam: jax.Array
    alpha: jax.Array
    beta: jax.Array


def normal_gamma_prior(
    shape: tuple[int, ...],
    mean: jax.Array | float,
    mean_count: jax.Array | float = 1.0,
    precision: jax.Array | float = 1.0,
    precision_count: jax.Array | float = 1.0,
    dtype=jnp.float32,
) -> NormalGamma:
    """The prior ``[mu0, n_mu, tau0, n_tau]`` as ``(mu0, n_mu, n_tau/2, (n_tau/2)/tau0)``, broadcast to ``shape``."""
    full = lambda x: jnp.broadcast_to(jnp.asarray(x, dtype), shape)  # noqa: E731
    half = jnp.asarray(precision_count, dtype) / 2
    return NormalGamma(mu=full(mean), lam=full(mean_count), alpha=full(half), beta=full(half / precision))


def normal_gamma_observe(post: NormalGamma, index: tuple, x: jax.Array) -> NormalGamma:
    """Fold one observation ``x`` into the posterior at ``index`` (e.g. ``(s, a)``).

    ``lam' = lam + 1``, ``mu' = (lam mu + x) / lam'``, ``alpha' = alpha + 1/2``,
    ``beta' = beta + lam (x - mu)^2 / (2 lam')``; applied one reward at a time this equals the batch update
    (docs/agents.md §1).
    """
    mu, lam = post.mu[index], post.lam[index]
    lam_new = lam + 1
    x = jnp.asarray(x, post.mu.dtype)
    return NormalGamma(
        mu=post.mu.at[index].set((lam * mu + x) / lam_new),
        lam=post.lam.at[index].set(lam_new),
        alpha=post.alpha.at[index].add(0.5),
        beta=post.beta.at[index].add(0.5 * lam * (x - mu) ** 2 / lam_new),
    )


def normal_gamma_mean(post: NormalGamma) -> jax.Array:
    """Posterior mean of the reward mean: ``mu``."""
    return post.mu


def normal_gamma_sample(
    key: jax.Array, post: NormalGamma, log_gamma: LogGammaSampler = log_gamma_sample
) -> jax.Array:
    """One draw of the mean reward: ``tau ~ Gamma(alpha, rate beta)``, ``m ~ N(mu, 1/(lam tau))`` (not clipped).

    The precision is drawn in log space (``log_gamma``, as in :func:`dirichlet_sample`) and the standard deviation
    capped at ``e^30`` so a sample is always finite.
    """
    k_tau, k_m = jax.random.split(key)
    log_tau = log_gamma(k_tau, post.alpha) - jnp.log(post.beta)
    log_std = jnp.minimum(-0.5 * (jnp.log(post.lam) + log_tau), _MAX_LOG_STD)
    return post.mu + jnp.exp(log_std) * jax.random.normal(k_m, post.mu.shape, post.mu.dtype)
