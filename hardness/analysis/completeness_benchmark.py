"""The completeness test on the committed benchmark results (:mod:`hardness.analysis.completeness`, paper §2.3).

Reads the ``members.csv`` of benchmark run folders (``jaxmdp-benchmark run``): for every setting and learning agent,
the per-step normalised regret of every (MDP, seed), taken from the folder with the most seeds of that agent and
setting (:func:`read_regrets`). Computes the measures of every MDP of a setting (:func:`benchmark_measures`):

* the paper's three (``variant="paper"``: ``diameter``, ``value_norm``, ``sum_reciprocal_gaps``) and the reference's
  diameter and value norm (``variant="colosseum"``: ``diameter_colosseum``, ``value_norm_colosseum``; its gap sum
  equals the paper's);
* ``distribution_mismatch``: the optimal policy's against the uniformly random policy's state distribution;
* continuous settings only: ``mixing_time`` of the optimal policy's lazy chain (``eps = 1/4``), ``bias_span``
  (``sp(h*)``) and ``gap_constant`` (Burnetas & Katehakis's constant).

The MDP of seed ``s`` is built with seed ``s`` (docs/benchmark.md §2); the measures are computed for the seeds asked
for (``measure_seeds``), and :func:`measure_matrix` pairs every regret seed with its own MDP's measure where it was
computed, else with the mean over the computed seeds (the benchmark report's rule for its hardness figures, which
average seeds 0-4).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hardness.analysis import completeness as cp
from hardness.analysis import measure_evaluation

__all__ = [
    "MEASURES",
    "CONTINUOUS_ONLY",
    "PAIR",
    "read_regrets",
    "benchmark_measures",
    "write_measures",
    "read_measures",
    "measure_matrix",
    "evaluate",
    "markdown_table",
    "write_csv",
    "completeness_figure",
]

#: The measures of :func:`benchmark_measures`, in table order.
MEASURES: tuple[str, ...] = (
    "diameter", "value_norm", "sum_reciprocal_gaps", "diameter_colosseum", "value_norm_colosseum",
    "distribution_mismatch", "mixing_time", "bias_span", "gap_constant",
)
#: Measures defined for continuous MDPs only.
CONTINUOUS_ONLY: tuple[str, ...] = measure_evaluation.CONTINUOUS_ONLY
#: The paper's pair (§3.3, Figure 2: the MDPs placed by diameter and value norm), under each variant.
PAIR: tuple[tuple[str, str], ...] = (("diameter", "value_norm"), ("diameter_colosseum", "value_norm_colosseum"))


# ---------------------------------------------------------------------------------------------------------------
# Inputs
# ---------------------------------------------------------------------------------------------------------------


def read_regrets(
    folders: Sequence[str | Path], *, random_agents: bool = False
) -> dict[tuple[str, str], dict[str, Any]]:
    """``{(set, agent): {"regret": {mdp: {seed: per-step regret}}, "folder": path, "steps": n}}`` from the
    ``members.csv`` of ``folders``; for each (set, agent) the folder that covers the most MDPs wins, then the one
    with the most seeds on each of them (its fewest), the first on a tie: a folder still being filled (a 20-seed run
    with some MDPs done) does not displace a finished run of fewer seeds. Agents whose name starts with ``random``
    are left out unless ``random_agents``."""
    best: dict[tuple[str, str], dict[str, Any]] = {}
    for folder in folders:
        path = Path(folder) / "members.csv"
        if not path.exists():
            raise ValueError(f"folders: {folder} has no members.csv")
        found: dict[tuple[str, str], dict[str, Any]] = {}
        with path.open(newline="") as f:
            for r in csv.DictReader(f):
                if r["agent"].startswith("random") and not random_agents:
                    continue
                entry = found.setdefault((r["set"], r["agent"]), {"regret": {}, "folder": Path(folder),
                                                                   "steps": int(r["steps"])})
                regret = float(r["normalized_cumulative_regret"]) / float(r["steps"])
                entry["regret"].setdefault(r["mdp"], {})[int(r["seed"])] = regret
        for key, entry in found.items():
            if key not in best or _coverage(entry) > _coverage(best[key]):
                best[key] = entry
    return best


def _coverage(entry: Mapping[str, Any]) -> tuple[int, int]:
    """``(MDPs, fewest seeds of an MDP)`` of a :func:`read_regrets` entry, compared in that order."""
    return len(entry["regret"]), min(len(v) for v in entry["regret"].values())


def benchmark_measures(
    set_name: str, seeds: Sequence[int], *, variants: Sequence[str] = ("paper", "colosseum"), n_buckets: int = 6
) -> list[dict[str, Any]]:
    """:data:`MEASURES` of every MDP of the benchmark set ``set_name`` at every seed of ``seeds``: one row per
    ``(mdp, seed)`` with ``set``, ``mdp``, ``seed`` and the measures (NaN where not defined, and for a variant left
    out of ``variants``)."""
    import hardness
    from hardness.benchmark import sets
    from jaxmdp.batching import size_buckets, stack

    keys = [(i.label, int(s)) for i in sets.instances(set_name) for s in seeds]
    found = {i.label: i for i in sets.instances(set_name)}
    mdps = [found[label].build(s) for label, s in keys]
    rows = [dict(set=sets.canonical_name(set_name), mdp=label, seed=s) for label, s in keys]
    for variant, suffix in (("paper", ""), ("colosseum", "_colosseum")):
        if variant not in variants:
            continue
        m = hardness.measures_many(mdps, variant=variant, n_buckets=n_buckets)
        names = ("diameter", "value_norm", "sum_reciprocal_gaps") if variant == "paper" else ("diameter", "value_norm")
        for name in names:
            values = np.asarray(getattr(m, name).value, np.float64)
            for row, v in zip(rows, values):
                row[name + suffix] = float(v)
    continuous = not mdps[0].episodic
    for group in size_buckets(mdps, n_buckets):
        out = measure_evaluation.extra_of_batch(stack([mdps[g] for g in group]).strip(), continuous)
        for name, values in out.items():
            for g, v in zip(group, np.asarray(values, np.float64)):
                rows[g][name] = float(v)
    for row in rows:
        for name in MEASURES:
            row.setdefault(name, math.nan)
    return rows


_COLUMNS = ("set", "mdp", "seed", *MEASURES)


def write_measures(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """Write measure rows (:func:`benchmark_measures`) as CSV, atomically."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(_COLUMNS)
        for r in rows:
            w.writerow([r["set"], r["mdp"], r["seed"], *(f"{r[m]:.9g}" for m in MEASURES)])
    tmp.replace(path)


def read_measures(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a file written by :func:`write_measures`."""
    with Path(path).open(newline="") as f:
        return [dict(set=r["set"], mdp=r["mdp"], seed=int(r["seed"]), **{m: float(r[m]) for m in MEASURES})
                for r in csv.DictReader(f)]


def measure_matrix(
    rows: Sequence[Mapping[str, Any]], set_name: str, mdps: Sequence[str], seeds: Sequence[int], measure: str
) -> np.ndarray:
    """``out[m, s]``: ``measure`` of MDP ``mdps[m]`` at seed ``seeds[s]`` from measure ``rows`` of ``set_name``
    (module docstring): its own value where the seed was measured, else the mean over the measured seeds (NaN when a
    measured value is NaN; ``ValueError`` when an MDP has no measured seed)."""
    by_mdp: dict[str, dict[int, float]] = {}
    for r in rows:
        if r["set"] == set_name:
            by_mdp.setdefault(r["mdp"], {})[int(r["seed"])] = float(r[measure])
    out = np.empty((len(mdps), len(seeds)))
    for i, mdp in enumerate(mdps):
        got = by_mdp.get(mdp)
        if not got:
            raise ValueError(f"rows hold no measure of {set_name} / {mdp}")
        mean = float(np.mean(list(got.values())))
        out[i] = [got.get(int(s), mean) for s in seeds]
    return out


# ---------------------------------------------------------------------------------------------------------------
# The test and its outputs
# ---------------------------------------------------------------------------------------------------------------


def evaluate(
    regrets: Mapping[tuple[str, str], Mapping[str, Any]],
    measure_rows: Sequence[Mapping[str, Any]],
    *,
    n_boot: int = 1000,
    seed: int = 0,
) -> dict[tuple[str, str], dict[str, Any]]:
    """For every (set, agent) of ``regrets`` (:func:`read_regrets`): the :class:`~hardness.analysis.completeness.
    Correlation` of every measure defined in the set and of :data:`PAIR` (leave-one-MDP-out), all on one set of
    two-stage draws (``n_boot`` resamples from ``seed``), and :func:`~hardness.analysis.completeness.best_shares`
    among the candidates that use all MDPs. Returns ``{(set, agent): {"results", "best", "n_mdps", "n_seeds",
    "folder"}}``."""
    out = {}
    for (set_name, agent), entry in sorted(regrets.items()):
        mdps = sorted(entry["regret"])
        seeds = sorted(set.intersection(*(set(v) for v in entry["regret"].values())))
        if not seeds:
            raise ValueError(f"{set_name} / {agent}: no seed common to all MDPs")
        regret = np.asarray([[entry["regret"][m][s] for s in seeds] for m in mdps])
        draws = cp.draw_resamples(len(mdps), len(seeds), n_boot, seed)
        names = [m for m in MEASURES if not (set_name.startswith("episodic") and m in CONTINUOUS_ONLY)]
        mats = {m: measure_matrix(measure_rows, set_name, mdps, seeds, m) for m in names}
        results = [cp.correlation(m, mats[m], regret, draws) for m in names]
        for a, b in PAIR:
            results.append(cp.combined_correlation(f"{a} + {b}", [mats[a], mats[b]], regret, draws))
        complete = [r for r in results if r.n_mdps == len(mdps)]
        out[(set_name, agent)] = dict(results=results, best=cp.best_shares(complete), n_mdps=len(mdps),
                                      n_seeds=len(seeds), folder=entry["folder"])
    return out


def _f(x: float) -> str:
    return "n/a" if not np.isfinite(x) else f"{x:+.2f}"


def markdown_table(evaluation: Mapping[tuple[str, str], Mapping[str, Any]]) -> str:
    """One table per (set, agent): a row per candidate with Spearman's rho and Kendall's tau-b, their 95% intervals,
    the share of resamples in which it has the highest rho, and the MDPs that entered; the best point estimate in
    bold."""
    parts = []
    for (set_name, agent), e in evaluation.items():
        best = max((r for r in e["results"] if np.isfinite(r.spearman)), key=lambda r: r.spearman, default=None)
        parts.append(f"### {set_name}, {agent} ({e['n_mdps']} MDPs, {e['n_seeds']} seeds)\n")
        parts.append("| measure | Spearman rho [95% CI] | Kendall tau-b [95% CI] | best in | MDPs |")
        parts.append("|---|---|---|---|---|")
        for r in e["results"]:
            name = f"**{r.name}**" if r is best else r.name
            share = e["best"].get(r.name)
            parts.append(f"| {name} | {_f(r.spearman)} [{_f(r.spearman_ci[0])}, {_f(r.spearman_ci[1])}] | "
                         f"{_f(r.kendall)} [{_f(r.kendall_ci[0])}, {_f(r.kendall_ci[1])}] | "
                         f"{'' if share is None else f'{100 * share:.0f}%'} | {r.n_mdps} |")
        parts.append("")
    return "\n".join(parts)


def write_csv(path: str | Path, evaluation: Mapping[tuple[str, str], Mapping[str, Any]]) -> None:
    """One row per (set, agent, candidate) with the numbers of :func:`markdown_table`."""
    with Path(path).open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["set", "agent", "measure", "spearman", "spearman_lo", "spearman_hi", "kendall", "kendall_lo",
                    "kendall_hi", "best_share", "n_mdps", "n_seeds", "folder"])
        for (set_name, agent), e in evaluation.items():
            for r in e["results"]:
                share = e["best"].get(r.name, math.nan)
                w.writerow([set_name, agent, r.name, *(f"{v:.4f}" for v in (r.spearman, *r.spearman_ci, r.kendall,
                                                                             *r.kendall_ci, share)),
                            r.n_mdps, e["n_seeds"], Path(e["folder"]).name])


def completeness_figure(evaluation: Mapping[tuple[str, str], Mapping[str, Any]], set_name: str,
                        path: str | Path | None = None) -> Any:
    """Dot-and-interval chart of one setting: a panel per agent, Spearman and Kendall of every candidate with their
    95% intervals; written to ``path`` when given."""
    from matplotlib.figure import Figure

    keys = [k for k in evaluation if k[0] == set_name]
    if not keys:
        raise ValueError(f"set_name {set_name!r} has no results; sets: {sorted({k[0] for k in evaluation})}")
    fig = Figure(figsize=(3.9 * len(keys) + 1.6, 4.2), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(keys), sharey=True))
    for ax, key in zip(axes, keys):
        e = evaluation[key]
        results = e["results"]
        ypos = np.arange(len(results))[::-1]
        for attr, colour, dy in (("spearman", "C0", 0.12), ("kendall", "C1", -0.12)):
            est = np.asarray([getattr(r, attr) for r in results])
            ci = np.asarray([getattr(r, f"{attr}_ci") for r in results])
            err = np.abs(np.stack([est - ci[:, 0], ci[:, 1] - est]))
            ax.errorbar(est, ypos + dy, xerr=np.nan_to_num(err), fmt="o", ms=4, color=colour, capsize=2,
                        label=("Spearman rho" if attr == "spearman" else "Kendall tau-b") if ax is axes[0] else None)
        ax.axvline(0.0, color="0.6", lw=0.8)
        ax.set_xlim(-1.05, 1.05)
        ax.set_yticks(ypos, [r.name.replace("_", " ") for r in results], fontsize=7)
        ax.set_title(f"{key[1]} ({e['n_seeds']} seeds)", fontsize=9)
        ax.set_xlabel("rank correlation with per-step regret", fontsize=8)
        ax.grid(alpha=0.3)
    fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    fig.suptitle(f"Completeness on the benchmark: {set_name} (20 MDPs; 95% two-stage bootstrap intervals)",
                 fontsize=10)
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig
