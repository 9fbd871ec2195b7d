"""Figures of the empirical hardness analysis in the paper's style (paper §3.2, App. D, Fig. 1).

One panel per scenario: every normalised measure against the swept parameter, as the mean over seeds with its 95%
percentile-bootstrap confidence band over seeds (the paper: "95% bootstrapped confidence intervals over twelve
random seeds"). The bootstrap is numpy with an explicit seed, so a figure is reproducible. It is the percentile
bootstrap of ``scipy.stats.bootstrap(..., method="percentile")``, written out because a sweep has non-finite entries
(an infinite diameter) and may have a single seed, where scipy's gives NaN for the whole column or refuses; here the
non-finite entries are left out of each resample's mean. Figures are built on
:class:`matplotlib.figure.Figure` directly, so plotting touches neither pyplot's global figures nor the backend.

Curves are keyed by name, so an extra measure (e.g. the normalised regret of a tuned near-optimal agent) is one more
entry of the ``curves`` mapping.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from jaxmdp._checks import check_int

__all__ = ["LABELS", "AXIS_LABELS", "bootstrap_means", "bootstrap_ci", "scenario_figure", "plot_scenario"]

#: Legend labels of the known curves (anything else is labelled by its key).
LABELS: Mapping[str, str] = {
    "diameter": "Diameter",
    "value_norm": "Environmental value norm",
    "sum_reciprocal_gaps": "Sum of reciprocals of sub-optimality gaps",
    "agent_regret": "Cumulative regret of the tuned near-optimal agent",
}

#: x-axis labels of the swept parameters.
AXIS_LABELS: Mapping[str, str] = {
    "p_rand": "Probability of random action ($p_\\mathrm{rand}$)",
    "p_lazy": "Probability of lazy action ($p_\\mathrm{lazy}$)",
    "n_states": "Number of states",
}


def bootstrap_means(samples: np.ndarray, n_resamples: int = 1000, seed: int = 0) -> np.ndarray:
    """Bootstrap distribution of the mean over seeds: ``[n_resamples, n_values]``.

    ``samples[i, j]`` is seed ``i`` at grid value ``j``. Each resample draws ``n_seeds`` seeds with replacement
    (``numpy.random.default_rng(seed)``) and takes, at every grid value, the mean of the drawn seeds' finite entries
    (seeds are the sampling unit, so one draw serves all grid values). A resample with no finite entry at some value
    gives NaN there.
    """
    x = np.asarray(samples, np.float64)
    if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] < 1:
        raise ValueError(f"samples must have shape [n_seeds, n_values] with both >= 1; got {x.shape}")
    n_resamples = check_int("n_resamples", n_resamples)
    idx = np.random.default_rng(seed).integers(0, x.shape[0], size=(int(n_resamples), x.shape[0]))
    return _finite_mean(x[idx], axis=1)  # [B, n_seeds, n_values] -> [B, n_values]


def _finite_mean(x: np.ndarray, axis: int) -> np.ndarray:
    """Mean of the finite entries along ``axis``; NaN (without a warning) where there is none."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # "Mean of empty slice"
        return np.nanmean(np.where(np.isfinite(x), x, np.nan), axis=axis)


def bootstrap_ci(
    samples: np.ndarray, level: float = 0.95, n_resamples: int = 1000, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean over seeds and its percentile-bootstrap confidence interval, each ``[n_values]``.

    The mean is over the finite entries of each column (NaN if none); the interval is the ``(1 - level) / 2`` and
    ``(1 + level) / 2`` quantiles (numpy's default linear interpolation) of :func:`bootstrap_means`.
    """
    if not isinstance(level, (int, float)) or not 0.0 < float(level) < 1.0:
        raise ValueError(f"level must lie in (0, 1); got {level!r}")
    x = np.asarray(samples, np.float64)
    means = bootstrap_means(x, n_resamples, seed)
    alpha = (1.0 - float(level)) / 2.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # "All-NaN slice": a column without any finite resample
        lo, hi = np.nanquantile(means, [alpha, 1.0 - alpha], axis=0)  # over the finite resamples of each column
    return _finite_mean(x, axis=0), lo, hi


def scenario_figure(
    x: Sequence[float],
    curves: Mapping[str, np.ndarray],
    *,
    xlabel: str,
    title: str = "",
    level: float = 0.95,
    n_resamples: int = 1000,
    seed: int = 0,
) -> Figure:
    """A figure (a :class:`matplotlib.figure.Figure`, outside pyplot's state) with, for every ``curves[name]``
    (``[n_seeds, n_values]``, normalised), the mean over seeds against ``x`` and its bootstrap band
    (:func:`bootstrap_ci`). ``xlabel`` is a key of :data:`AXIS_LABELS` or free text. Points whose mean is NaN (no
    finite seed) are left out of the line."""
    x = np.asarray(x, np.float64)
    if x.ndim != 1:
        raise ValueError(f"x must be one-dimensional; got shape {x.shape}")
    if not curves:
        raise ValueError("curves must not be empty")
    fig = Figure(figsize=(5.0, 3.6), dpi=150)
    ax = fig.subplots()
    for name, values in curves.items():
        values = np.asarray(values, np.float64)
        if values.ndim != 2 or values.shape[1] != x.size:
            raise ValueError(f"curves[{name!r}] must have shape [n_seeds, {x.size}]; got {values.shape}")
        mean, lo, hi = bootstrap_ci(values, level, n_resamples, seed)
        ok = np.isfinite(mean)
        (line,) = ax.plot(x[ok], mean[ok], marker="o", markersize=3, label=LABELS.get(name, name))
        ax.fill_between(x[ok], lo[ok], hi[ok], color=line.get_color(), alpha=0.2, linewidth=0)
    ax.set_xlabel(AXIS_LABELS.get(xlabel, xlabel))
    ax.set_ylabel("Normalised value")
    if title:
        ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def plot_scenario(
    x: Sequence[float],
    curves: Mapping[str, np.ndarray],
    path: str | Path,
    *,
    xlabel: str,
    title: str = "",
    level: float = 0.95,
    n_resamples: int = 1000,
    seed: int = 0,
) -> Path:
    """Write :func:`scenario_figure` of ``x`` and ``curves`` to a PNG at ``path`` (folders created); returns the path.
    Nothing is written when the arguments are invalid."""
    fig = scenario_figure(x, curves, xlabel=xlabel, title=title, level=level, n_resamples=n_resamples, seed=seed)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path
