"""Completeness on the benchmark (paper §2.3): how well each measure orders a setting's MDPs as a tuned agent's regret.

The paper calls a hardness measure *complete* when it orders MDPs as a near-optimal agent's regret does (§2.3) and
asks whether any is. On one benchmark setting (20 MDPs) and one tuned agent, with ``regret[m, s]`` the agent's
per-step normalised regret on MDP ``m`` at seed ``s`` (final ``normalized_cumulative_regret / steps``, App. E) and
``measure[m, s]`` a measure of the MDP that seed ``s`` builds (the benchmark builds MDP ``m`` of seed ``s`` with seed
``s``, docs/benchmark.md §2):

* **point estimate**: Spearman's rho and Kendall's tau-b (scipy: ``scipy.stats.spearmanr``,
  ``scipy.stats.kendalltau(..., variant="b")``) between the per-MDP means over seeds ``x_m = mean_s measure[m, s]``
  and ``y_m = mean_s regret[m, s]``; ``+1`` when the measure orders the MDPs exactly as the regret does;
* **interval**: a two-stage (MDPs, then seeds within MDPs) percentile bootstrap, the MDP and the seed being the two
  sources of chance (which MDPs a benchmark holds; which runs an agent made): each of ``n_boot`` resamples draws
  ``n_mdps`` MDPs with replacement and, for each draw independently, ``n_seeds`` of that MDP's seeds with replacement;
  the measure and the regret of a drawn MDP are the means over its drawn seeds; the interval is the 2.5% and 97.5%
  percentiles (numpy's linear) of the resampled correlations (:func:`draw_resamples`, :func:`resample_means`).
  ``scipy.stats.bootstrap`` resamples single observations, not such nested clusters, hence numpy's draws;
* **two measures together** (:func:`loo_predictions`): leave one MDP out; on the others, scale each measure to
  ``[0, 1]`` by its minimum and maximum over them (App. E's normalisation, range 0 mapped to 0) and fit by least
  squares ``log(y + REGRET_OFFSET) ~ b0 + b1 z1 + b2 z2``; predict the held-out MDP with the same scaling; the pair's
  correlation is that of the held-out predictions with ``y``. In a bootstrap resample the MDP left out takes all its
  copies with it, so that a prediction never sees its own MDP;
* **how sure**: beside the intervals, ``best_share``: the share of the (shared) resamples in which a candidate's rho is
  the highest of the candidates compared (:func:`best_shares`).

An MDP whose measure is not finite at some seed (an infinite diameter, a chain that never mixes) is left out of that
measure's correlation (``n_mdps`` says how many entered). A constant input has no ranking: its correlation is NaN.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence

import numpy as np
from scipy import stats

__all__ = [
    "REGRET_OFFSET",
    "Correlation",
    "rank_correlations",
    "draw_resamples",
    "resample_means",
    "correlation",
    "loo_predictions",
    "combined_correlation",
    "best_shares",
]

#: Added to the per-step regret before the logarithm of the pair's linear model (a thousandth of the normalised range,
#: so that an MDP the agent solves, regret about 0, stays finite).
REGRET_OFFSET = 1e-3


@dataclasses.dataclass(frozen=True)
class Correlation:
    """Rank correlation of one candidate (a measure, or a pair) with the regret over a setting's MDPs: point
    estimates, 95% two-stage bootstrap intervals, the MDPs that entered, and the resampled Spearman rhos (kept for
    :func:`best_shares`; NaN where a resample has no ranking)."""

    name: str
    spearman: float
    spearman_ci: tuple[float, float]
    kendall: float
    kendall_ci: tuple[float, float]
    n_mdps: int
    boot_spearman: np.ndarray = dataclasses.field(repr=False, compare=False)


def rank_correlations(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """``(Spearman's rho, Kendall's tau_b)`` of ``x`` and ``y`` by scipy; NaN for fewer than two entries or a constant
    input (scipy's ``ConstantInputWarning`` is expected there and silenced)."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    if x.size < 2:
        return float("nan"), float("nan")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", stats.ConstantInputWarning)
        rho = stats.spearmanr(x, y)[0]
        tau = stats.kendalltau(x, y, variant="b")[0]
    return float(rho), float(tau)


def draw_resamples(n_mdps: int, n_seeds: int, n_boot: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The two-stage bootstrap draws (module docstring) from ``numpy.random.default_rng(seed)``: ``mdp_idx[b, j]``,
    the ``j``-th MDP of resample ``b`` (``n_mdps`` draws with replacement), then ``seed_idx[b, j, k]`` (``n_seeds``
    seed positions with replacement for each drawn MDP)."""
    for name, v in (("n_mdps", n_mdps), ("n_seeds", n_seeds), ("n_boot", n_boot)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{name} must be a positive integer; got {v!r}")
    rng = np.random.default_rng(seed)
    mdp_idx = rng.integers(0, n_mdps, size=(n_boot, n_mdps))
    seed_idx = rng.integers(0, n_seeds, size=(n_boot, n_mdps, n_seeds))
    return mdp_idx, seed_idx


def resample_means(values: np.ndarray, mdp_idx: np.ndarray, seed_idx: np.ndarray) -> np.ndarray:
    """``out[b, j] = mean_k values[mdp_idx[b, j], seed_idx[b, j, k]]``: every resample's per-MDP means over its drawn
    seeds (``values[m, s]`` per MDP and seed)."""
    values = np.asarray(values, np.float64)
    return values[mdp_idx[..., None], seed_idx].mean(axis=-1)


def _check_pair(measure: np.ndarray, regret: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    measure, regret = np.asarray(measure, np.float64), np.asarray(regret, np.float64)
    if measure.ndim != 2 or measure.shape != regret.shape:
        raise ValueError(f"measure and regret must be [n_mdps, n_seeds] arrays of one shape; got {measure.shape} and "
                         f"{regret.shape}")
    if not np.all(np.isfinite(regret)):
        raise ValueError("regret must be finite")
    return measure, regret


def _percentiles(samples: np.ndarray) -> tuple[float, float]:
    s = np.asarray(samples, np.float64)
    s = s[np.isfinite(s)]
    if s.size == 0:
        return float("nan"), float("nan")
    lo, hi = np.percentile(s, [2.5, 97.5])
    return float(lo), float(hi)


def _finite_rows(*arrays: np.ndarray) -> np.ndarray:
    return np.all([np.all(np.isfinite(a), axis=1) for a in arrays], axis=0)


def _row_spearman(x: np.ndarray, y: np.ndarray, chunk: int = 500) -> np.ndarray:
    """Spearman's rho of every row pair ``(x[b], y[b])`` by scipy: ``spearmanr`` of a block of rows (``axis=1``)
    correlates every row with every other, and the ``(x[b], y[b])`` entries are read off (one call per ``chunk``
    rows instead of one per row); NaN for a constant row."""
    # scipy answers NaN for the whole block when any row is constant: those rows (NaN by definition) stay out.
    out = np.full(len(x), np.nan)
    ranked = np.flatnonzero((np.ptp(x, axis=1) > 0) & (np.ptp(y, axis=1) > 0))
    for start in range(0, len(ranked), chunk):
        rows = ranked[start:start + chunk]
        n = len(rows)
        if n == 1:
            out[rows[0]] = stats.spearmanr(x[rows[0]], y[rows[0]])[0]
            continue
        matrix = stats.spearmanr(np.concatenate([x[rows], y[rows]]), axis=1)[0]
        out[rows] = matrix[np.arange(n), n + np.arange(n)]
    return out


def _boot(xb: np.ndarray, yb: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``[n_boot, 2]``: (rho, tau_b) of every resample's kept entries (scipy; Spearman in blocks when every entry
    is kept, :func:`_row_spearman`)."""
    if keep.all():
        rho = _row_spearman(xb, yb)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", stats.ConstantInputWarning)
            tau = np.asarray([stats.kendalltau(a, b, variant="b")[0] for a, b in zip(xb, yb)], np.float64)
        return np.column_stack([rho, tau])
    return np.asarray([rank_correlations(xb[b][keep[b]], yb[b][keep[b]]) for b in range(len(xb))])


def correlation(
    name: str, measure: np.ndarray, regret: np.ndarray, draws: tuple[np.ndarray, np.ndarray]
) -> Correlation:
    """:class:`Correlation` of ``measure[m, s]`` with ``regret[m, s]`` (module docstring), the interval from
    ``draws`` (:func:`draw_resamples` over all MDPs and seeds). MDPs whose measure is not finite at some seed are left
    out: of the point estimate, and of every resample (the remaining draws of a resample are kept)."""
    measure, regret = _check_pair(measure, regret)
    mdp_idx, seed_idx = draws
    ok = _finite_rows(measure)
    x, y = measure[ok].mean(axis=1), regret[ok].mean(axis=1)
    rho, tau = rank_correlations(x, y)
    safe = np.where(np.isfinite(measure), measure, 0.0)
    xb, yb = resample_means(safe, mdp_idx, seed_idx), resample_means(regret, mdp_idx, seed_idx)
    boot = _boot(xb, yb, ok[mdp_idx])
    return Correlation(name, rho, _percentiles(boot[:, 0]), tau, _percentiles(boot[:, 1]), int(ok.sum()), boot[:, 0])


def loo_predictions(features: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None) -> np.ndarray:
    """Leave-one-MDP-out predictions of ``log(y + REGRET_OFFSET)`` from ``features[n, k]`` (module docstring):
    for each ``j``, a least-squares fit of ``1, z_1 .. z_k`` on the entries of the other groups (``z`` each feature
    min-max scaled over them; a feature constant there scales to 0) evaluated at entry ``j``. An affine scaling moves
    no least-squares prediction, so the scaling matters only there: a measure constant on the training MDPs is
    ignored rather than extrapolated. ``groups[j]`` names
    the MDP of entry ``j`` (default: every entry its own); the entries sharing ``j``'s group are left out with it."""
    f = np.asarray(features, np.float64)
    y = np.asarray(y, np.float64)
    if f.ndim != 2 or f.shape[0] != y.shape[0] or y.ndim != 1:
        raise ValueError(f"features must be [n, k] and y [n]; got {f.shape} and {y.shape}")
    groups = np.arange(len(y)) if groups is None else np.asarray(groups)
    target = np.log(np.maximum(y, 0.0) + REGRET_OFFSET)
    out = np.full(len(y), np.nan)
    for j in range(len(y)):
        train = groups != groups[j]
        if train.sum() < 2:
            continue
        lo, hi = f[train].min(axis=0), f[train].max(axis=0)
        scale = np.where(hi > lo, hi - lo, 1.0)
        z = np.where(hi > lo, (f - lo) / scale, 0.0)
        X = np.column_stack([np.ones(len(y)), z])
        beta = np.linalg.lstsq(X[train], target[train], rcond=None)[0]
        out[j] = X[j] @ beta
    return out


def combined_correlation(
    name: str, measures: Sequence[np.ndarray], regret: np.ndarray, draws: tuple[np.ndarray, np.ndarray]
) -> Correlation:
    """:class:`Correlation` of the leave-one-MDP-out predictions from several ``measures[i][m, s]`` together
    (:func:`loo_predictions`) with the regret; intervals from ``draws`` as :func:`correlation` (in a resample the
    predictions are made again, each drawn MDP left out with all its copies)."""
    if len(measures) < 1:
        raise ValueError("measures must hold at least one measure")
    checked = [_check_pair(m, regret)[0] for m in measures]
    regret = np.asarray(regret, np.float64)
    mdp_idx, seed_idx = draws
    ok = _finite_rows(*checked)
    f = np.column_stack([m[ok].mean(axis=1) for m in checked])
    y = regret[ok].mean(axis=1)
    rho, tau = rank_correlations(loo_predictions(f, y), y)
    safe = [np.where(np.isfinite(m), m, 0.0) for m in checked]
    fb = np.stack([resample_means(m, mdp_idx, seed_idx) for m in safe], axis=-1)
    yb = resample_means(regret, mdp_idx, seed_idx)
    keep = ok[mdp_idx]
    pred = np.full(yb.shape, np.nan)
    for b in range(len(mdp_idx)):
        k = keep[b]
        pred[b, k] = loo_predictions(fb[b][k], yb[b][k], mdp_idx[b][k])
    boot = _boot(pred, yb, keep & np.isfinite(pred))
    return Correlation(name, rho, _percentiles(boot[:, 0]), tau, _percentiles(boot[:, 1]), int(ok.sum()), boot[:, 0])


def best_shares(results: Sequence[Correlation]) -> dict[str, float]:
    """For candidates computed on the same draws: the share of resamples in which each one's Spearman rho is the
    highest (ties share the resample equally; resamples where some candidate has no rho are left out)."""
    if not results:
        return {}
    boot = np.stack([r.boot_spearman for r in results])
    fine = np.all(np.isfinite(boot), axis=0)
    boot = boot[:, fine]
    if boot.shape[1] == 0:
        return {r.name: float("nan") for r in results}
    top = boot == boot.max(axis=0)
    share = (top / top.sum(axis=0)).mean(axis=1)
    return {r.name: float(s) for r, s in zip(results, share)}

