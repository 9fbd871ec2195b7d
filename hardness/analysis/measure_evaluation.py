"""How well does a hardness measure order MDPs as a near-optimal agent's regret does? (paper §2.3's completeness)

The paper calls a measure *complete* when it orders MDPs as the regret of a near-optimal agent does (§2.3), and reads
completeness off its figures by eye. Here it is a number: for the rows of a scenario sweep (``jaxmdp-sweep``,
scenarios 1-4: one row per ``(seed, value)`` MDP with its measures and the tuned near-optimal
agent's regret), the rank correlation between each measure and the regret, pooled over all rows:

* Spearman's ``rho``: Pearson's correlation of the mid-ranks (ties get the mean of the ranks they span);
* Kendall's ``tau_b`` (Kendall 1945, "The treatment of ties in ranking problems"):
  ``(n_c - n_d) / sqrt((n_0 - n_x)(n_0 - n_y))`` over all pairs, ``n_c``/``n_d`` the concordant/discordant pairs,
  ``n_0 = n(n-1)/2`` and ``n_x``, ``n_y`` the pairs tied in ``x``, in ``y``.

Both are computed by scipy (``scipy.stats.spearmanr``, ``scipy.stats.kendalltau(..., variant="b")``), a dependency
already, rather than by code of ours. Both are ``+1`` when the measure orders the MDPs exactly as the regret does.
Their 95% intervals are percentile bootstrap intervals over seeds: each resample draws the sweep's seeds with
replacement and pools the rows of the drawn seeds (a seed's MDPs share their construction randomness, so seeds are the
independent unit, as in the scenario figures; ``scipy.stats.bootstrap`` resamples single observations, not such
clusters, hence the numpy draw). Rows where a measure is not finite (an infinite diameter, a chain that never mixes) are left out of that
measure's correlation. A constant input has no ranking: its correlation is NaN.

Beside the sweep's three measures, :func:`extra_measures` computes on the same MDPs, rebuilt from the sweep's
settings (its JSON), the two measures of Table 1 that the paper could not (:func:`hardness.mixing_time` of the optimal
policy's lazy chain, and :func:`hardness.distribution_mismatch` of the optimal policy against the uniformly random
one) and two from the regret bounds (:func:`hardness.bias_span`, :func:`hardness.gap_constant`); all but the mismatch
are defined for continuous MDPs only (NaN in the episodic setting).
"""

from __future__ import annotations

import ast
import csv
import dataclasses
import functools
import json
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np
from matplotlib.figure import Figure
from scipy import stats

from hardness.analysis import scenarios
from hardness.bias_span import bias_span
from hardness.gap_constant import gap_constant
from hardness.mismatch import distribution_mismatch
from hardness.mixing import mixing_time
from jaxmdp import dynamic_programming as dp
from jaxmdp._checks import check_int
from jaxmdp.mdp import MDP

__all__ = [
    "REGRET_COLUMN",
    "EXTRA_MEASURES",
    "Correlation",
    "read_sweep",
    "extra_measures",
    "extra_of_batch",
    "correlations",
    "markdown_table",
    "evaluation_figure",
]

#: The regret the measures are compared with: the tuned agent's per-step normalised cumulative regret (App. E; the
#: curve of the scenario figures before their min-max scaling).
REGRET_COLUMN = "agent_normalized_cumulative_regret"
#: Names of the measures :func:`extra_measures` adds (:func:`extra_of_batch`).
EXTRA_MEASURES = ("mixing_time", "distribution_mismatch", "bias_span", "gap_constant")
#: Those of them defined for continuous MDPs only.
CONTINUOUS_ONLY = ("mixing_time", "bias_span", "gap_constant")


# ---------------------------------------------------------------------------------------------------------------
# Rank correlations
# ---------------------------------------------------------------------------------------------------------------


def _rank_correlations(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """``(Spearman's rho, Kendall's tau_b)`` of ``x`` and ``y`` (scipy.stats, module docstring); NaN for fewer than
    two entries or a constant input (scipy's ``ConstantInputWarning`` is expected there and silenced)."""
    if len(x) < 2:
        return float("nan"), float("nan")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", stats.ConstantInputWarning)
        rho = stats.spearmanr(x, y)[0]
        tau = stats.kendalltau(x, y, variant="b")[0]
    return float(rho), float(tau)


@dataclasses.dataclass(frozen=True)
class Correlation:
    """Rank correlation of one measure with the regret: point estimates on all rows, 95% bootstrap intervals over
    seeds, and how many rows (finite measure) entered."""

    measure: str
    spearman: float
    spearman_ci: tuple[float, float]
    kendall: float
    kendall_ci: tuple[float, float]
    n_rows: int


def correlations(
    rows: Sequence[Mapping[str, Any]],
    measures: Sequence[str],
    *,
    regret: str = REGRET_COLUMN,
    n_boot: int = 1000,
    seed: int = 0,
) -> list[Correlation]:
    """:class:`Correlation` of each measure in ``measures`` with ``regret`` over ``rows`` (dicts holding ``seed``,
    the measures and the regret), with percentile bootstrap intervals over seeds (``numpy.random.default_rng(seed)``,
    ``n_boot`` resamples; module docstring)."""
    n_boot = check_int("n_boot", n_boot)
    if not rows:
        raise ValueError("rows must hold at least one row")
    missing = [c for c in [regret, *measures] if c not in rows[0]]
    if missing:
        raise ValueError(f"rows lack the columns {missing}; they have {sorted(rows[0])}")
    seeds = np.asarray([r["seed"] for r in rows])
    unique = np.unique(seeds)
    by_seed = [np.nonzero(seeds == s)[0] for s in unique]
    y = np.asarray([r[regret] for r in rows], np.float64)
    draws = np.random.default_rng(seed).integers(0, len(unique), size=(n_boot, len(unique)))
    out = []
    for m in measures:
        x = np.asarray([r[m] for r in rows], np.float64)
        ok = np.isfinite(x) & np.isfinite(y)
        boot = []
        for d in draws:
            idx = np.concatenate([by_seed[i] for i in d])
            idx = idx[ok[idx]]
            boot.append(_rank_correlations(x[idx], y[idx]))
        rho, tau = _rank_correlations(x[ok], y[ok])
        boot_s, boot_k = zip(*boot)
        out.append(Correlation(
            measure=m,
            spearman=rho,
            spearman_ci=_percentiles(boot_s),
            kendall=tau,
            kendall_ci=_percentiles(boot_k),
            n_rows=int(ok.sum()),
        ))
    return out


def _percentiles(samples: Sequence[float]) -> tuple[float, float]:
    s = np.asarray(samples, np.float64)
    s = s[np.isfinite(s)]
    if s.size == 0:
        return float("nan"), float("nan")
    lo, hi = np.percentile(s, [2.5, 97.5])
    return float(lo), float(hi)


# ---------------------------------------------------------------------------------------------------------------
# Sweep tables and the extra measures
# ---------------------------------------------------------------------------------------------------------------


def read_sweep(csv_path: str | Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The rows of a sweep table (numbers parsed; empty cells dropped) and its settings (the JSON beside it)."""
    csv_path = Path(csv_path)
    rows = []
    with csv_path.open(newline="") as f:
        for rec in csv.DictReader(f):
            row: dict[str, Any] = {}
            for k, v in rec.items():
                if v == "" or v is None:
                    continue
                try:
                    row[k] = ast.literal_eval(v)
                except (ValueError, SyntaxError):
                    row[k] = v
            rows.append(row)
    json_path = csv_path.with_suffix(".json")
    config = json.loads(json_path.read_text()) if json_path.exists() else {}
    return rows, config


def _spec_of(rows: Sequence[Mapping[str, Any]], config: Mapping[str, Any]) -> scenarios.ScenarioSpec:
    seeds = sorted({int(r["seed"]) for r in rows})
    params = {k: ast.literal_eval(v) for k, v in config.get("params", {}).items()}
    size_param = scenarios.FAMILY_DEFAULTS[config["family"]].size_param
    if config["scenario"] in (3, 4):
        params.pop(size_param, None)
    params.pop(config["parameter"], None)
    return scenarios.scenario_spec(
        config["scenario"], config["family"], episodic=config["setting"] == "episodic", seeds=seeds,
        values=config["values"], params={k: v for k, v in params.items() if v is not None},
        variant=config.get("variant", "paper"), gamma=config.get("gamma", 0.99),
    )


def extra_measures(rows: Sequence[Mapping[str, Any]], config: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """:data:`EXTRA_MEASURES` of every row's MDP (rebuilt with :func:`hardness.analysis.scenarios.prepare` from the
    sweep's settings), in the order of ``rows`` (:func:`extra_of_batch`; NaN where not defined)."""
    spec = _spec_of(rows, config)
    grid = scenarios.prepare(spec)
    batch = scenarios.grid_mdps(grid)
    out = extra_of_batch(batch, not spec.episodic)
    V = len(spec.values)
    pos = {(s, v): i * V + j for i, s in enumerate(grid.seeds) for j, v in enumerate(spec.values)}
    idx = np.asarray([pos[(int(r["seed"]), r["value"])] for r in rows])
    return {name: np.asarray(out.get(name, np.full(len(pos), np.nan)), np.float64)[idx] for name in EXTRA_MEASURES}


@functools.partial(jax.jit, static_argnames=("continuous",))
def extra_of_batch(batch: MDP, continuous: bool) -> dict[str, jax.Array]:
    """The measures of :data:`EXTRA_MEASURES` of every member of a stacked ``batch`` (one setting; ``continuous``
    static), mapped with ``lax.map`` so that each member's solvers stop at its own convergence: the distribution
    mismatch coefficient of the optimal policy against the uniformly random one (Table 1), and for continuous MDPs
    the mixing time (``eps = 1/4``) of the optimal policy's lazy chain (Table 1), the span of the optimal bias
    ``sp(h*)`` (Bartlett & Tewari 2009) and Burnetas & Katehakis's gap constant (docs/measures.md §7.3-7.4).
    Returns ``{name: [M]}``, the continuous-only names absent for an episodic batch."""

    def one(m):
        out = {"distribution_mismatch": distribution_mismatch(m, None, dp.uniform_policy(m)).value}
        if continuous:
            out.update(mixing_time=mixing_time(m, lazy=True).value, bias_span=bias_span(m).value,
                       gap_constant=gap_constant(m).value)
        return out

    return jax.lax.map(one, batch)


# ---------------------------------------------------------------------------------------------------------------
# Outputs
# ---------------------------------------------------------------------------------------------------------------


def _fmt(x: float) -> str:
    return "n/a" if not np.isfinite(x) else f"{x:+.2f}"


def markdown_table(results: Mapping[str, Sequence[Correlation]]) -> str:
    """One Markdown table: a row per (scenario, measure) with both correlations and their intervals."""
    lines = [
        "| scenario | measure | Spearman rho [95% CI] | Kendall tau-b [95% CI] | rows |",
        "|---|---|---|---|---|",
    ]
    for name, corrs in results.items():
        for c in corrs:
            lines.append(
                f"| {name} | {c.measure} | {_fmt(c.spearman)} [{_fmt(c.spearman_ci[0])}, {_fmt(c.spearman_ci[1])}] "
                f"| {_fmt(c.kendall)} [{_fmt(c.kendall_ci[0])}, {_fmt(c.kendall_ci[1])}] | {c.n_rows} |"
            )
    return "\n".join(lines) + "\n"


def evaluation_figure(
    results: Mapping[str, Sequence[Correlation]], path: str | Path | None = None, columns: int = 3
) -> Figure:
    """Dot-and-interval chart: one panel per scenario (at most ``columns`` to a row), Spearman and Kendall of every
    measure with their 95% intervals; written to ``path`` when given."""
    names = list(results)
    columns = check_int("columns", columns)
    n_cols = min(max(len(names), 1), columns)
    n_rows = -(-max(len(names), 1) // n_cols)
    fig = Figure(figsize=(4.2 * n_cols, 3.0 * n_rows + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(n_rows, n_cols, sharey=True)).ravel()
    for ax in axes[len(names):]:
        ax.set_visible(False)
    for ax, name in zip(axes, names):
        corrs = list(results[name])
        ypos = np.arange(len(corrs))
        for k, (attr, colour, dy) in enumerate((("spearman", "C0", -0.12), ("kendall", "C1", 0.12))):
            est = np.asarray([getattr(c, attr) for c in corrs])
            ci = np.asarray([getattr(c, f"{attr}_ci") for c in corrs])
            err = np.abs(np.stack([est - ci[:, 0], ci[:, 1] - est]))
            label = "Spearman rho" if attr == "spearman" else "Kendall tau-b"
            ax.errorbar(est, ypos + dy, xerr=np.nan_to_num(err), fmt="o", color=colour, capsize=3,
                        label=label if ax is axes[0] else None)
        ax.axvline(0.0, color="0.6", lw=0.8)
        ax.set_xlim(-1.05, 1.05)
        ax.set_yticks(ypos, [c.measure for c in corrs])
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("rank correlation with the agent's regret")
    if names:
        fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig
