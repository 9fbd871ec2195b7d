"""The binomial helpers of tests/stat_checks.py against direct sums."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stat_checks import allowed_failures, failure_rate_bound, mostly


def binom_sf(m: int, n: int, q: float) -> float:
    """P(Binomial(n, q) > m) summed term by term."""
    return math.fsum(math.comb(n, k) * q**k * (1 - q) ** (n - k) for k in range(m + 1, n + 1))


@pytest.mark.parametrize("n, q, alpha", [(32, 1e-3, 1e-7), (64, 0.003, 1e-7), (16, 0.02, 1e-7), (200, 0.01, 1e-6),
                                         (8, 0.0, 1e-7), (10, 1.0, 1e-7), (5, 0.5, 0.1)])
def test_allowed_failures_is_the_least_m(n, q, alpha):
    m = allowed_failures(n, q, alpha)
    assert binom_sf(m, n, q) <= alpha
    assert m == 0 or binom_sf(m - 1, n, q) > alpha


@pytest.mark.parametrize("failures, n", [(0, 1000), (0, 7), (3, 500), (40, 100)])
def test_failure_rate_bound_is_clopper_pearson(failures, n):
    q = failure_rate_bound(failures, n, miss=1e-3)
    # P(Binomial(n, q) <= failures) = miss at the bound, larger below it.
    at = 1 - binom_sf(failures, n, q)
    assert at == pytest.approx(1e-3, rel=1e-6)
    assert 1 - binom_sf(failures, n, q * 0.99) > 1e-3
    if failures == 0:
        assert q == pytest.approx(1 - 1e-3 ** (1 / n), rel=1e-9)
    assert failure_rate_bound(n, n) == 1.0
    with pytest.raises(ValueError, match="failures"):
        failure_rate_bound(n + 1, n)


def test_mostly_allows_m_failures_and_names_the_members():
    m = allowed_failures(40, 0.01)
    passed = np.ones(40, bool)
    passed[:m] = False
    mostly(passed, 0.01, "ok")
    passed[m] = False
    with pytest.raises(AssertionError, match=rf"{m + 1} of 40 seeds failed .* members \[0, 1"):
        mostly(passed, 0.01, "too many")
    with pytest.raises(ValueError, match="allow them all to fail"):
        mostly(np.ones(4, bool), 0.5, "too few seeds")
    with pytest.raises(ValueError, match="q must"):
        allowed_failures(4, 1.5)
