"""Aggregate scores across a benchmark's MDPs with confidence intervals: the interquartile mean and the stratified
bootstrap of Agarwal et al. 2021, "Deep reinforcement learning at the edge of the statistical precipice" (§4; the
convention of the ``rliable`` library).

An agent's scores on a setting form a matrix ``scores[n, m]``, run (seed) ``n`` on task (MDP) ``m``, ``N x M``.

* **Interquartile mean** (IQM): the mean of the middle half of the ``N M`` scores pooled over runs and tasks,
  ``scipy.stats.trim_mean(scores, 0.25, axis=None)``: with ``k = floor(N M / 4)``, the ``k`` lowest and the ``k``
  highest scores are dropped and the rest averaged with equal weights. This is rliable's definition
  (``rliable.metrics.aggregate_iqm`` calls exactly this); when ``N M`` is not a multiple of 4 it keeps more than half
  of the scores rather than giving the boundary scores fractional weights (for six scores ``[0, 1, 2, 4, 8, 100]``:
  ``(1 + 2 + 4 + 8) / 4 = 3.75``, where fractional weights would give ``(1/2 + 2 + 4 + 8/2) / 3 = 3.5``). Unlike the
  median it uses half of the data; unlike the mean one outlying run cannot move it far.
* **Stratified bootstrap**: a resample draws, for every task independently, ``N`` of that task's runs with
  replacement (``scores*[n, m] = scores[I[n, m], m]``, ``I`` i.i.d. uniform on ``0..N-1``); runs never move between
  tasks, and the set of tasks is kept (the tasks are the benchmark, not a sample of it). The interval is the percentile
  interval, the ``(1 - level) / 2`` and ``(1 + level) / 2`` quantiles (numpy's linear interpolation) of the
  statistic over the resamples, as rliable's default ``method="percentile"``.

This module implements both with numpy and ``scipy.stats.trim_mean`` rather than depending on rliable: rliable pulls
in ``arch``, ``statsmodels``, ``pandas`` and ``seaborn`` for two short computations, and draws its resamples from
numpy's global random state, whereas here ``seed`` fixes every interval.

The score of the benchmark report is ``members.csv``'s ``normalized_regret_per_step`` as it is: the per-step
normalised cumulative regret of App. E (docs/benchmark.md §2), already normalised per MDP by the optimal and the worst
policy (0 = optimal, 1 = the worst policy), so the MDPs share one scale and can be pooled. Lower is better.
"""

from __future__ import annotations

import csv
import dataclasses
import os
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from jaxmdp._checks import check_int

__all__ = [
    "SCORE_FIELD",
    "N_RESAMPLES",
    "Interval",
    "iqm",
    "mean",
    "stratified_resamples",
    "stratified_bootstrap",
    "read_members",
    "score_matrix",
    "aggregate_table",
]

#: The ``members.csv`` column aggregated by default (module docstring): lower is better.
SCORE_FIELD = "normalized_regret_per_step"
#: Default number of bootstrap resamples ``B``. The Monte Carlo standard error of a 95% percentile endpoint is about
#: ``sqrt(0.025 * 0.975 / B) / f(q)`` (``f`` the bootstrap density at the quantile): for a roughly normal bootstrap
#: distribution under 1% of the interval's width at this ``B``.
N_RESAMPLES = 10_000
#: Resampled scores held in memory at once (the resamples are drawn in blocks of at most this many entries).
_BLOCK_ENTRIES = 1 << 21


@dataclasses.dataclass(frozen=True)
class Interval:
    """A point estimate with its stratified-bootstrap percentile interval.

    Attributes:
      estimate: the statistic of the scores.
      low, high: the ``(1 - level) / 2`` and ``(1 + level) / 2`` quantiles of the statistic over the resamples.
      level: the interval's nominal coverage.
      n_runs, n_tasks: the score matrix's shape ``N x M``.
    """

    estimate: float
    low: float
    high: float
    level: float
    n_runs: int
    n_tasks: int


def _pooled(scores: Any) -> np.ndarray:
    x = np.asarray(scores, np.float64)
    if x.ndim < 2:
        raise ValueError(f"scores must be a [runs, tasks] matrix (or a stack of them); got shape {x.shape}")
    return x.reshape(*x.shape[:-2], -1)


def iqm(scores: Any) -> float | np.ndarray:
    """Interquartile mean of ``scores[..., N, M]`` over its last two axes (runs x tasks pooled): the 25%-trimmed mean
    ``scipy.stats.trim_mean(..., 0.25)``, rliable's ``aggregate_iqm`` (module docstring)."""
    out = stats.trim_mean(_pooled(scores), 0.25, axis=-1)
    return float(out) if np.ndim(out) == 0 else out


def mean(scores: Any) -> float | np.ndarray:
    """Mean of ``scores[..., N, M]`` over its last two axes (every run of every task, equal weights)."""
    out = _pooled(scores).mean(axis=-1)
    return float(out) if np.ndim(out) == 0 else out


def _check_scores(scores: Any) -> np.ndarray:
    x = np.asarray(scores, np.float64)
    if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] < 1:
        raise ValueError(f"scores must be a [runs, tasks] matrix with at least one of each; got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("scores must be finite (a missing run has no score: leave its task out)")
    return x


def stratified_resamples(scores: Any, n_resamples: int, rng: np.random.Generator) -> np.ndarray:
    """``n_resamples`` stratified bootstrap resamples ``[n_resamples, N, M]`` of ``scores[N, M]``: entry
    ``[b, n, m]`` is ``scores[I[b, n, m], m]`` with ``I = rng.integers(0, N, (n_resamples, N, M))`` (each task's runs
    drawn with replacement, independently per task; module docstring)."""
    x = _check_scores(scores)
    n_resamples = check_int("n_resamples", n_resamples)
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator; got {type(rng).__name__}")
    N, M = x.shape
    idx = rng.integers(0, N, size=(n_resamples, N, M))
    return x[idx, np.arange(M)]


def stratified_bootstrap(
    scores: Any,
    statistic: Callable[[np.ndarray], Any] = iqm,
    *,
    n_resamples: int = N_RESAMPLES,
    level: float = 0.95,
    seed: int = 0,
) -> Interval:
    """``statistic`` of ``scores[N, M]`` (runs x tasks) and its stratified-bootstrap percentile interval.

    ``statistic`` maps ``[..., N, M]`` to ``[...]`` (reducing the last two axes, as :func:`iqm` and :func:`mean` do).
    The resamples are :func:`stratified_resamples` drawn from ``numpy.random.default_rng(seed)`` in blocks of at most
    ``2**21`` scores, so the interval depends on ``(scores, statistic, n_resamples, level, seed)`` only. The
    endpoints are the ``(1 - level) / 2`` and ``(1 + level) / 2`` quantiles (numpy's linear interpolation) of the
    ``n_resamples`` statistics.
    """
    x = _check_scores(scores)
    n_resamples = check_int("n_resamples", n_resamples)
    if isinstance(level, bool) or not isinstance(level, (int, float)) or not 0.0 < float(level) < 1.0:
        raise ValueError(f"level must lie in (0, 1); got {level!r}")
    seed = check_int("seed", seed, low=0)
    rng = np.random.default_rng(seed)
    block = max(1, _BLOCK_ENTRIES // x.size)
    values = []
    for start in range(0, n_resamples, block):
        values.append(np.asarray(statistic(stratified_resamples(x, min(block, n_resamples - start), rng)),
                                 np.float64).reshape(-1))
    boot = np.concatenate(values)
    alpha = (1.0 - float(level)) / 2.0
    low, high = np.quantile(boot, [alpha, 1.0 - alpha])
    return Interval(float(statistic(x)), float(low), float(high), float(level), x.shape[0], x.shape[1])


# ---------------------------------------------------------------------------------------------------------------
# The benchmark's members table
# ---------------------------------------------------------------------------------------------------------------


def read_members(path: str | os.PathLike) -> list[dict[str, str]]:
    """The rows of a benchmark run's ``members.csv`` (:data:`hardness.benchmark.tables.MEMBER_FIELDS`), as dicts of
    strings."""
    with Path(path).open(newline="") as f:
        return list(csv.DictReader(f))


def _table(rows: Iterable[Mapping[str, Any]], field: str) -> dict[str, dict[tuple[str, str, int], float]]:
    """``{set: {(agent, mdp, seed): score}}``, refusing a member that appears twice."""
    out: dict[str, dict[tuple[str, str, int], float]] = {}
    for r in rows:
        missing = [c for c in ("set", "mdp", "agent", "seed", field) if c not in r]
        if missing:
            raise ValueError(f"members rows must hold the columns set, mdp, agent, seed and {field!r}; a row lacks "
                             f"{missing}")
        key = (str(r["agent"]), str(r["mdp"]), int(r["seed"]))
        cell = out.setdefault(str(r["set"]), {})
        if key in cell:
            raise ValueError(f"members rows hold {key} of set {r['set']!r} twice")
        cell[key] = float(r[field])
    return out


def _complete(cell: Mapping[tuple[str, str, int], float]) -> tuple[list[str], list[str], list[int]]:
    """Agents and MDPs in order of first appearance, and the sorted seeds; only the MDPs on which every agent has
    every seed are kept, so that every agent is aggregated over the same runs and tasks."""
    agents = list(dict.fromkeys(a for a, _, _ in cell))
    mdps = list(dict.fromkeys(m for _, m, _ in cell))
    seeds = sorted({s for _, _, s in cell})
    done = [m for m in mdps if all((a, m, s) in cell for a in agents for s in seeds)]
    return agents, done, seeds


def score_matrix(
    rows: Iterable[Mapping[str, Any]], set_name: str, agent: str, *, field: str = SCORE_FIELD
) -> tuple[np.ndarray, list[str], list[int]]:
    """``(scores [seeds, MDPs], MDPs, seeds)`` of ``agent`` on ``set_name`` from members rows (:func:`read_members`,
    or dicts with the same columns): the column ``field`` on the set's MDPs on which every agent of the set has every
    seed of the set (in order of first appearance; the seeds sorted)."""
    table = _table(rows, field)
    if set_name not in table:
        raise ValueError(f"set_name must be one of the rows' sets {sorted(table)}; got {set_name!r}")
    cell = table[set_name]
    agents, mdps, seeds = _complete(cell)
    if agent not in agents:
        raise ValueError(f"agent must be one of the agents of set {set_name!r}: {agents}; got {agent!r}")
    return _matrix(cell, agent, mdps, seeds), mdps, seeds


def _matrix(cell: Mapping[tuple[str, str, int], float], agent: str, mdps: list[str], seeds: list[int]) -> np.ndarray:
    return np.asarray([[cell[(agent, m, s)] for m in mdps] for s in seeds], np.float64).reshape(len(seeds), len(mdps))


def _fmt(iv: Interval) -> str:
    return f"{iv.estimate:.3f} [{iv.low:.3f}, {iv.high:.3f}]"


def aggregate_table(
    members: str | os.PathLike | Iterable[Mapping[str, Any]],
    *,
    field: str = SCORE_FIELD,
    n_resamples: int = N_RESAMPLES,
    level: float = 0.95,
    seed: int = 0,
) -> str:
    """Markdown: per setting (the ``set`` column), a table with one row per agent of the IQM and the mean of
    ``field`` across runs and MDPs, each with its stratified-bootstrap percentile interval
    (:func:`stratified_bootstrap`, ``level``, ``n_resamples`` resamples from ``seed``), over the MDPs on which every agent of the setting has every
    seed (:func:`score_matrix`; the table says so when that is not all of them).

    ``members`` is a ``members.csv`` path or its rows (several runs' rows may be concatenated, one row per set, MDP,
    agent and seed). Settings and agents keep their order of first appearance.
    """
    rows = read_members(members) if isinstance(members, (str, os.PathLike)) else list(members)
    table = _table(rows, field)
    pct = f"{100 * float(level):g}%"
    lines = []
    for set_name, cell in table.items():
        agents, mdps, seeds = _complete(cell)
        n_all = len({m for _, m, _ in cell})
        lines += [f"### {set_name}", ""]
        scope = f"{len(mdps)} MDPs x {len(seeds)} seeds"
        if len(mdps) < n_all:
            scope += f" (the {len(mdps)} of the {n_all} MDPs on which every agent has every seed)"
        lines += [f"`{field}` (lower is better) across {scope}; {pct} stratified-bootstrap percentile intervals, "
                  f"{n_resamples:,} resamples, seed {seed}.", ""]
        if not mdps:
            lines += ["No MDP has every agent's every seed yet.", ""]
            continue
        lines += [f"| agent | IQM [{pct} CI] | mean [{pct} CI] |", "|---|---|---|"]
        for a in agents:
            scores = _matrix(cell, a, mdps, seeds)
            cells = [_fmt(stratified_bootstrap(scores, f, n_resamples=n_resamples, level=level, seed=seed))
                     for f in (iqm, mean)]
            lines.append(f"| {a} | {cells[0]} | {cells[1]} |")
        lines.append("")
    return "\n".join(lines)
