"""Statistical checks with a stated false-failure probability, and the seed of the statistical tests.

Every check compares a statistic with bounds that a correct sampler leaves with probability at most ``ALPHA = 1e-7``:
the exact distribution of the statistic where it is known (a binomial count of draws below an exact quantile, a
chi-square sum of squared Gaussians, a normal or Gamma sum, the Kolmogorov-Smirnov statistic's distribution), and
otherwise Bernstein's inequality for bounded variables (no normal approximation). A test's false-failure probability
is at most its number of checks times ``ALPHA``; tests state it and mark themselves ``statistical(p=...)`` so that
``tests/fresh_seed_check.py`` can re-run them on fresh seeds.

The seed: ``seed(default)`` is ``default`` unless ``JAXMDP_TEST_SEED`` is set, in which case it is a value derived
from both (different tests get different streams for the same fresh seed).
"""

from __future__ import annotations

import os

import jax
import numpy as np
from scipy import stats

ALPHA = 1e-7
SEED_VARIABLE = "JAXMDP_TEST_SEED"


def seed(default: int) -> int:
    """``default``, or with ``$JAXMDP_TEST_SEED`` set a seed below 2**31 derived from it and ``default``."""
    fresh = os.environ.get(SEED_VARIABLE)
    if fresh is None:
        return default
    return int(np.random.SeedSequence([int(fresh), default]).generate_state(1)[0] >> 1)


def key(default: int) -> jax.Array:
    return jax.random.key(seed(default))


def rng(default: int) -> np.random.Generator:
    return np.random.default_rng(seed(default))


class Checks:
    """Counts a test's checks, each failing a correct sampler with probability at most ``alpha``."""

    def __init__(self, alpha: float = ALPHA) -> None:
        self.n = 0
        self.alpha = alpha

    def false_failure_bound(self) -> float:
        return self.n * self.alpha

    def _two_sided(self, dist) -> tuple[float, float]:
        return dist.ppf(self.alpha / 2), dist.isf(self.alpha / 2)

    def chi2(self, total: float, dof: float, what: str) -> None:
        """``total ~ chi2(dof)`` exactly."""
        self.n += 1
        lo, hi = self._two_sided(stats.chi2(dof))
        assert lo <= total <= hi, f"{what}: chi2({dof}) statistic {total} outside [{lo}, {hi}]"

    def normal(self, z: float, what: str) -> None:
        """``z ~ N(0, 1)`` exactly."""
        self.n += 1
        bound = stats.norm.isf(self.alpha / 2)
        assert abs(z) <= bound, f"{what}: z = {z} beyond {bound}"

    def gamma_sum(self, total: float, shape: float, what: str) -> None:
        """``total`` is a sum of independent Gamma(a_i, 1): exactly Gamma(sum a_i, 1)."""
        self.n += 1
        lo, hi = self._two_sided(stats.gamma(shape))
        assert lo <= total <= hi, f"{what}: Gamma({shape}) sum {total} outside [{lo}, {hi}]"

    def binomial(self, count: int, n: int, p: float, what: str) -> None:
        """``count ~ Binomial(n, p)`` exactly."""
        self.n += 1
        lo, hi = self._two_sided(stats.binom(n, p))
        assert lo <= count <= hi, f"{what}: count {count} of {n} outside [{lo}, {hi}] (p = {p})"

    def below_quantiles(self, x: np.ndarray, ppf, probs, what: str) -> None:
        """i.i.d. ``x`` with quantile function ``ppf``: the count below each exact quantile is Binomial(n, p)."""
        for p in probs:
            self.binomial(int(np.sum(x <= ppf(p))), x.size, p, f"{what}: below its {p} quantile")

    def ks(self, x: np.ndarray, cdf, what: str) -> None:
        """i.i.d. ``x`` with a continuous CDF: the exact Kolmogorov-Smirnov p-value is uniform, above ``ALPHA``."""
        self.n += 1
        p = stats.kstest(x, cdf).pvalue
        assert p > self.alpha, f"{what}: Kolmogorov-Smirnov p-value {p}"

    def bernstein(self, x: np.ndarray, mean: float, var: float, bound: float, what: str) -> None:
        """i.i.d. ``x`` with mean ``mean``, variance at most ``var`` and ``|x - mean| <= bound``: Bernstein's
        inequality, P(|x̄ - mean| >= t) <= 2 exp(-n t^2 / (2 var + 2 bound t / 3)), solved for the ``t`` at which the
        right side is ``alpha``."""
        self.bernstein_mean(float(x.mean()), x.size, mean, var, bound, what)

    def bernstein_mean(self, sample_mean: float, n: int, mean: float, var: float, bound: float, what: str) -> None:
        """:meth:`bernstein` given only the mean ``sample_mean`` of the ``n`` draws."""
        self.n += 1
        log_term = np.log(2 / self.alpha)
        t = (bound * log_term / 3 + np.sqrt((bound * log_term / 3) ** 2 + 2 * n * var * log_term)) / n
        assert abs(sample_mean - mean) <= t, f"{what}: mean {sample_mean} differs from {mean} by more than {t}"

    def bounded_moments(self, x: np.ndarray, dist, lo: float, hi: float, what: str) -> None:
        """Mean and variance of i.i.d. ``x`` in ``[lo, hi]`` against the scipy distribution ``dist`` (2 Bernstein
        checks: on ``x`` and on ``(x - mean)^2``, whose mean is the variance and variance ``mu_4 - sigma^4``)."""
        mean, var, excess_kurtosis = (float(x) for x in dist.stats(moments="mvk"))
        mu4 = (excess_kurtosis + 3.0) * var**2
        self.bernstein(x, mean, var, max(hi - mean, mean - lo), f"{what}: mean")
        reach = max(hi - mean, mean - lo) ** 2
        self.bernstein((x - mean) ** 2, var, max(mu4 - var**2, 0.0), max(reach - var, var), f"{what}: variance")

    def independent_signs(self, x: np.ndarray, y: np.ndarray, median_x: float, median_y: float, what: str) -> None:
        """Pairs ``(x_i, y_i)`` i.i.d. across ``i`` with ``x_i`` independent of ``y_i`` and exact medians: the count
        of pairs on the same side of their medians is Binomial(n, 1/2)."""
        self.binomial(int(np.sum((x <= median_x) == (y <= median_y))), x.size, 0.5, f"{what}: sign agreement")


# ---------------------------------------------------------------------------------------------------------------
# Learning tests: n seeds in lockstep, at most m of them may miss the criterion
# ---------------------------------------------------------------------------------------------------------------
#
# A learning test's criterion (e.g. "the final policy is optimal") fails a correct agent on some seeds with an unknown
# per-seed probability q. It is measured once on N fresh seeds (``tests/probe_failure_rates.py``), bounded above by
# the Clopper-Pearson bound ``q_u`` at miss probability ``MEASURE_MISS`` (``failure_rate_bound``), and the test then
# runs n independent seeds and allows m failures, the least m with P(Binomial(n, q_u) > m) <= ALPHA
# (``allowed_failures``). Given q <= q_u the test fails a correct agent with probability at most ALPHA.

MEASURE_MISS = 1e-3

# The members of a learning test must be independent for its failure count to be dominated by Binomial(n, q): every
# member of a grid has its own key (tests/agent_loop.grid_seeds). Members may differ in their failure rates (two
# epsilons or learning rates): a sum of independent Bernoulli(q_i) exceeds m >= n q with at most the probability of
# Binomial(n, mean q_i) (Hoeffding 1956), and the measurement, on equally many members of each grid value, bounds that
# mean rate.


def failure_rate_bound(failures: int, n: int, miss: float = MEASURE_MISS) -> float:
    """Clopper-Pearson upper bound on a Bernoulli rate from ``failures`` of ``n``: the q at which
    P(Binomial(n, q) <= failures) = miss (0 failures: ``1 - miss^(1/n)``)."""
    if not 0 <= failures <= n or n < 1:
        raise ValueError(f"failures must lie in [0, n] and n >= 1, got failures={failures}, n={n}")
    if failures == n:
        return 1.0
    return float(stats.beta.isf(miss, failures + 1, n - failures))


def allowed_failures(n: int, q: float, alpha: float = ALPHA) -> int:
    """The least m with P(Binomial(n, q) > m) <= alpha."""
    if not 0.0 <= q <= 1.0:
        raise ValueError(f"q must lie in [0, 1], got {q}")
    dist = stats.binom(n, q)
    m = max(int(dist.isf(alpha)) - 1, 0)
    while dist.sf(m) > alpha:
        m += 1
    return m


def mostly(passed: np.ndarray, q: float, what: str, alpha: float = ALPHA) -> None:
    """``passed``: one boolean per independent seed, each False with probability at most ``q`` for a correct
    implementation. Fails when more than ``allowed_failures(n, q, alpha)`` are False: probability at most ``alpha``
    (the count of failures is dominated by Binomial(n, q))."""
    passed = np.asarray(passed, bool).ravel()
    m = allowed_failures(passed.size, q, alpha)
    if m >= passed.size:
        raise ValueError(f"{what}: {passed.size} seeds at a failure rate {q:.2g} allow them all to fail; use more seeds")
    failed = np.flatnonzero(~passed)
    assert failed.size <= m, (f"{what}: {failed.size} of {passed.size} seeds failed (allowed {m} at a per-seed "
                              f"rate <= {q:.2g}); failing members {failed[:20].tolist()}")
