"""The benchmark report (paper §3.3 Table 2, App. G Tables 9-12 and Figures 6-10) from a run's output folder.

Written by :func:`write_report` (called at the end of :func:`hardness.benchmark.run.run_benchmark`, or by
``jaxmdp-benchmark report DIR``) into the folder:

* ``report.md`` and ``report.tex``, per set:

  - the Table 2-style table: one row per MDP (numbered ``Family (k)`` within its family, as the paper), one column per
    agent with the mean ± standard deviation over seeds (``ddof = 1``) of the per-step normalised cumulative regret
    (final ``normalized_cumulative_regret / steps``, App. E), the lowest mean of the learning agents in bold (ties at
    the printed precision too; the random agent is a baseline, never bold), the paper's number of the agent beside
    it where the paper has one (Table 2 for the tabular agents; App. G's non-tabular table for the deep agents when
    the run's emission is the paper's ``state_info``, :func:`~hardness.benchmark.published.regret_table`), and the
    seeds completed; an *Average* row: mean ± standard deviation (``ddof = 0``) over the MDPs of the per-MDP means,
    Table 2's rule (when a run covers only some of a set's MDPs, the paper's average is recomputed by the same rule
    over the same MDPs, and the row says so);
  - the App. G-style table: one row per (MDP, agent): normalised cumulative reward, expected reward and regret, the
    paper's regret (as in the first table), steps per second of one member (``n_steps`` over its batch's lockstep run
    time) and completed seeds, ours and the paper's (tabular agents only; their runs were cut off after ten minutes);

* an *Aggregates across MDPs* section: per set, every agent's interquartile mean and mean of the per-step
  normalised regret pooled over seeds and MDPs with stratified-bootstrap intervals
  (:func:`hardness.benchmark.aggregate.aggregate_table`), the baseline's agents included;

* a *Compute* section: hours of compiling and running per (set, agent), summed from ``batches.csv``
  (:func:`compute_time`), with the members finished of those planned and the hosts that ran them;

* ``curves_<set>.png/.pdf``: the cumulative regret of every agent (mean over seeds) against the steps, one panel per
  MDP, with the random agent as baseline (its own runs when it was run, else the uniform policy's exact expected
  regret);
* ``hardness_<set>.png/.pdf``: the MDPs placed by diameter and environmental value norm (the reference's variant,
  :data:`MEASURE_VARIANT`, mean over the first five seeds as the reference's helper does, benchmark.md §4), one panel per learning agent, coloured by its
  mean per-step normalised regret (§3.3, Figure 2); the measures are cached in ``measures.csv``.

With ``baseline`` (:mod:`hardness.benchmark.baselines`: ``"committed"``, the shipped agents' committed results, or
another run folder) the agents of that source that this run did not run are set beside its own wherever they were
made under the same protocol: extra columns named ``agent (committed)`` (or the folder's name) in both tables and
panels in the hardness figure (their curves are not kept), with the paper's numbers of those agents; the report says
which source each comes from and which agents were left out, and why.

Figures are drawn on :class:`matplotlib.figure.Figure` objects (no pyplot, no global backend change).
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from hardness.benchmark import aggregate, baselines, published, sets

__all__ = ["Summary", "summarize", "markdown_table", "latex_table", "write_report", "LateRegret", "late_regret",
           "ComputeTime", "compute_time", "compute_table"]

#: Seeds whose hardness measures are averaged (the reference's helper averages seeds 0-4).
MEASURE_SEEDS = 5
#: The measures' variant: the reference's procedures (``hardness`` ``variant="colosseum"``), whose numbers place the
#: MDPs where the paper's figures do (its episodic diameter differs most from the exact one).
MEASURE_VARIANT = "colosseum"
_SHORT = {"MiniGridEmpty": "MG-Empty", "MiniGridRooms": "MG-Rooms"}


def _display_labels(labels: Sequence[str]) -> dict[str, str]:
    """``Family/scope`` -> ``Family (k)``, ``k`` counting within the family in order (the paper's numbering)."""
    count: dict[str, int] = defaultdict(int)
    out = {}
    for label in labels:
        family = label.split("/")[0]
        count[family] += 1
        out[label] = f"{_SHORT.get(family, family)} ({count[family]})"
    return out


class Summary:
    """Per set, the per-(MDP, agent) scores of a run folder's ``members.csv`` and ``batches.csv``.

    Attributes:
      settings: the run's ``plan.json`` settings.
      scores: ``{(set, mdp, agent): {field: [value per seed]}}``, the baseline's agents included.
      rates: ``{(set, mdp, agent): member steps per second}`` (the rate of the member's batch; the run's own agents).
      beside: what :func:`hardness.benchmark.baselines.select` took from ``baseline`` (``None`` without one).
      members: one dict per (set, MDP, agent, seed), ``members.csv``'s rows then the baseline's (``set``, ``mdp``,
        ``agent``, ``seed`` and the scores), for :func:`hardness.benchmark.aggregate.aggregate_table`.
    """

    def __init__(self, out: Path, baseline: str | os.PathLike | None = None):
        self.out = Path(out)
        plan = json.loads((self.out / "plan.json").read_text())
        self.settings: dict[str, Any] = plan["settings"]
        self.batches: list[dict] = plan["batches"]
        self.scores: dict[tuple[str, str, str], dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
        batch_rate = {}
        if (self.out / "batches.csv").exists():
            with (self.out / "batches.csv").open(newline="") as f:
                batch_rate = {r["batch"]: float(r["member_steps_per_s"]) for r in csv.DictReader(f)}
        self.rates: dict[tuple[str, str, str], float] = {}
        self.members: list[dict[str, Any]] = []
        with (self.out / "members.csv").open(newline="") as f:
            for r in csv.DictReader(f):
                self.members.append(r)
                key = (r["set"], r["mdp"], r["agent"])
                for field in ("normalized_regret_per_step", "normalized_cumulative_reward",
                              "normalized_cumulative_expected_reward", "random_normalized_regret_per_step"):
                    self.scores[key][field].append(float(r[field]))
                self.rates[key] = batch_rate.get(r["batch"], math.nan)
        self.beside: baselines.Beside | None = None
        if baseline is not None:
            if Path(baseline).resolve() == self.out.resolve():
                raise ValueError(f"baseline {baseline} is the run's own folder")
            self.beside = baselines.select(self.settings, {s: self.labels(s) for s in self.settings["sets"]},
                                           baseline)
            for key, fields in self.beside.scores.items():
                self.scores[key] = defaultdict(list, {f: list(v) for f, v in fields.items()})
                set_name, mdp, agent = key
                for i, seed in enumerate(self.settings["seeds"]):
                    self.members.append(dict(set=set_name, mdp=mdp, agent=self.column(set_name, agent), seed=seed,
                                             **{f: v[i] for f, v in fields.items()}))

    @property
    def n_seeds(self) -> int:
        return len(self.settings["seeds"])

    @property
    def n_steps(self) -> int:
        return int(self.settings["n_steps"])

    def labels(self, set_name: str) -> list[str]:
        """The set's MDPs that the run holds, in the set's order."""
        planned = {label for b in self.batches if b["set_name"] == set_name for label, _ in b["members"]}
        return [i.label for i in sets.instances(set_name) if i.label in planned]

    def agents(self, set_name: str) -> list[str]:
        """The run's agents of ``set_name``, then the baseline's set beside them."""
        return list(self.settings["agents"][set_name]) + self.beside_agents(set_name)

    def beside_agents(self, set_name: str) -> list[str]:
        return list(self.beside.agents.get(set_name, [])) if self.beside is not None else []

    def column(self, set_name: str, agent: str) -> str:
        """An agent's column name: its name, marked with the baseline's label when it comes from there."""
        return f"{agent} ({self.beside.label})" if agent in self.beside_agents(set_name) else agent

    def cell(self, set_name: str, mdp: str, agent: str, field: str = "normalized_regret_per_step"):
        """``(mean, std, completed seeds)`` of ``field``; ``None`` when no seed has finished."""
        values = self.scores.get((set_name, mdp, agent), {}).get(field)
        if not values:
            return None
        x = np.asarray(values, np.float64)
        return float(x.mean()), float(x.std(ddof=1)) if x.size > 1 else 0.0, int(x.size)


def summarize(out: str | os.PathLike, baseline: str | os.PathLike | None = None) -> Summary:
    """The :class:`Summary` of a run folder, with ``baseline``'s comparable results beside its own (module
    docstring; ``ValueError`` naming what differs when none is comparable)."""
    return Summary(Path(out), baseline)


def _is_learning(agent: str) -> bool:
    return not agent.startswith("random")


def _fmt(mean: float, std: float, digits: int, bold: bool, latex: bool) -> str:
    m = f"{mean:.{digits}f}"
    if latex:
        return f"$\\mathbf{{{m}}} \\pm {std:.{digits}f}$" if bold else f"${m} \\pm {std:.{digits}f}$"
    return f"**{m}** ± {std:.{digits}f}" if bold else f"{m} ± {std:.{digits}f}"


def _table2_rows(s: Summary, set_name: str, latex: bool) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the Table 2-style table (module docstring)."""
    agents = s.agents(set_name)
    paper = published.regret_table(set_name, s.settings.get("emission"))
    paper_agents = [a for a in agents if a in paper]
    header = ["MDP"] + [s.column(set_name, a) for a in agents] + [f"{a} (paper)" for a in paper_agents] + ["seeds"]
    display = _display_labels([i.label for i in sets.instances(set_name)])
    rows, means = [], defaultdict(list)
    for label in s.labels(set_name):
        cells = {a: s.cell(set_name, label, a) for a in agents}
        learned = [round(c[0], 3) for a, c in cells.items() if c is not None and _is_learning(a)]
        best = min(learned) if learned else None
        row = [display[label]]
        for a in agents:
            c = cells[a]
            if c is None:
                row.append("")
                continue
            means[a].append(c[0])
            row.append(_fmt(c[0], c[1], 3, _is_learning(a) and round(c[0], 3) == best, latex))
        for a in paper_agents:
            p = paper[a].get(label)
            row.append(_fmt(p[0], p[1], 2, False, latex) if p else "")
        done = [c[2] for c in cells.values() if c is not None]
        row.append(f"{min(done) if len(done) == len(agents) else 0}/{s.n_seeds}")
        rows.append(row)
    labels, n_set = s.labels(set_name), len(sets.instances(set_name))
    name = "Average" if len(labels) == n_set else f"Average of these {len(labels)} of {n_set}"
    avg = [f"*{name}*" if not latex else f"\\textit{{{name}}}"]
    for a in agents:
        x = np.asarray(means[a])
        avg.append(_fmt(float(x.mean()), float(x.std()), 3, False, latex) if x.size else "")
    for a in paper_agents:
        if len(labels) == n_set:  # the whole set: the paper's own average row
            p = published.regret_average(set_name, a)
        else:  # a subset: the same rule (mean, std with ddof 0) over the paper's numbers of the MDPs shown
            x = np.asarray([q[0] for q in (paper[a].get(lb) for lb in labels) if q])
            p = (float(x.mean()), float(x.std())) if x.size else None
        avg.append(_fmt(p[0], p[1], 2, False, latex) if p else "")
    avg.append("")
    rows.append(avg)
    return header, rows


def _appendix_rows(s: Summary, set_name: str, latex: bool) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the App. G-style table (module docstring)."""
    header = ["MDP", "agent", "norm. cum. reward", "norm. cum. expected reward", "norm. cum. regret",
              "regret (paper)", "steps/s", "completed seeds", "completed (paper)"]
    display = _display_labels([i.label for i in sets.instances(set_name)])
    paper = published.regret_table(set_name, s.settings.get("emission"))
    rows = []
    for label in s.labels(set_name):
        for k, a in enumerate(s.agents(set_name)):
            regret = s.cell(set_name, label, a)
            if regret is None:
                continue
            fields = [s.cell(set_name, label, a, f) for f in ("normalized_cumulative_reward",
                                                               "normalized_cumulative_expected_reward")]
            fields = [(c[0] / s.n_steps, c[1] / s.n_steps) for c in fields]
            p, p_regret = published.appendix_g(set_name, a, label), paper.get(a, {}).get(label)
            rate = s.rates.get((set_name, label, a), math.nan)
            rows.append([display[label] if k == 0 else "", s.column(set_name, a)]
                        + [_fmt(m, sd, 3, False, latex) for m, sd in fields]
                        + [_fmt(regret[0], regret[1], 3, False, latex),
                           _fmt(*p_regret, 2, False, latex) if p_regret else "",
                           f"{rate:,.0f}" if math.isfinite(rate) else "",
                           f"{regret[2]}/{s.n_seeds}", f"{p.completed}/20" if p else ""])
    return header, rows


def _markdown(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(r) + " |" for r in rows]


def _latex(header: Sequence[str], rows: Sequence[Sequence[str]], caption: str) -> list[str]:
    esc = lambda t: t.replace("_", "\\_").replace("#", "\\#")  # noqa: E731
    lines = ["\\begin{table}[htb]", "\\centering", f"\\caption{{{esc(caption)}}}",
             "\\resizebox{\\textwidth}{!}{%", "\\begin{tabular}{l" + "r" * (len(header) - 1) + "}", "\\toprule",
             " & ".join(esc(h) for h in header) + " \\\\", "\\midrule"]
    lines += [" & ".join(esc(c) if "$" not in c else c for c in r) + " \\\\" for r in rows]
    return lines + ["\\bottomrule", "\\end{tabular}}", "\\end{table}", ""]


def markdown_table(s: Summary, set_name: str) -> str:
    """The Table 2-style table of ``set_name`` in Markdown."""
    return "\n".join(_markdown(*_table2_rows(s, set_name, latex=False)))


def latex_table(s: Summary, set_name: str) -> str:
    """The Table 2-style table of ``set_name`` in LaTeX (booktabs)."""
    caption = f"Per-step normalised cumulative regret, {set_name} ({s.n_steps:,} steps, {s.n_seeds} seeds)."
    return "\n".join(_latex(*_table2_rows(s, set_name, latex=True), caption))


# ---------------------------------------------------------------------------------------------------------------
# Figures
# ---------------------------------------------------------------------------------------------------------------


def _save(fig: Any, stem: Path) -> list[Path]:
    paths = [stem.with_suffix(".png"), stem.with_suffix(".pdf")]
    for p in paths:
        fig.savefig(p, dpi=120)
    return paths


def _finished_curves(out: Path, batches: Sequence[dict], set_name: str):
    """``(batch, its runs/<batch>.json record, its curves {"steps": [R], "cumulative_regret": [R, members],
    "random_cumulative_regret": [R, members]})`` for every batch of ``set_name`` that finished under its plan key."""
    for b in batches:
        saved, npz = out / "runs" / f"{b['id']}.json", out / "runs" / f"{b['id']}.curves.npz"
        if b["set_name"] != set_name or not (saved.exists() and npz.exists()):
            continue
        record = json.loads(saved.read_text())
        if record.get("key") != b["key"]:
            continue
        with np.load(npz) as z:
            yield b, record, {name: z[name] for name in z.files}


def _curves(s: Summary, set_name: str) -> dict[tuple[str, str], dict[str, np.ndarray]]:
    """``{(mdp, agent): {"steps": [R], "cumulative_regret": [seeds, R], "random_cumulative_regret": [seeds, R]}}``."""
    out: dict[tuple[str, str], dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for b, _, z in _finished_curves(s.out, s.batches, set_name):
        for i, (label, _) in enumerate(b["members"]):
            d = out[(label, b["agent"])]
            d["steps"] = z["steps"]
            d["cumulative_regret"].append(z["cumulative_regret"][:, i])
            d["random_cumulative_regret"].append(z["random_cumulative_regret"][:, i])
    return {k: {n: np.asarray(v) for n, v in d.items()} for k, d in out.items()}


class LateRegret(NamedTuple):
    """An agent's per-step normalised regret on a set (mean over each MDP's seeds, then over the MDPs): ``end``, the
    score at the run's end; ``late``, the rate over the run's last steps; ``projected``, the score at ``horizon`` had
    the late rate held (``nan`` without a horizon); ``n_mdps``, the MDPs with finished runs."""

    end: float
    late: float
    projected: float
    n_mdps: int


def late_regret(
    out: str | os.PathLike, set_name: str, fraction: float = 0.2, horizon: int | None = None
) -> dict[str, LateRegret]:
    """Whether the agents of a run folder still learn at its end, per agent of ``set_name`` (App. E's per-step
    normalised regret, :class:`LateRegret`), from every finished batch's curves, however many have finished.

    A member's normalised regret is ``k C(t)`` with ``C`` its cumulative regret and ``k`` its MDP's normalising
    constant (``normalized_cumulative_regret / cumulative_regret`` at the end). With ``n`` the run's steps and ``t0``
    the first record at or after ``(1 - fraction) n``: ``end = k C(n) / n``, ``late = k (C(n) - C(t0)) / (n - t0)``
    and ``projected = k (C(n) + (horizon - n) late_rate) / horizon``, the score at ``horizon`` steps if the regret went
    on accruing at its late rate: below ``end`` while the agent still learns, and an upper bound of the longer run's
    score when its rate keeps falling. A member with no regret at the end counts ``0`` in each.
    """
    if not 0 < fraction < 1:
        raise ValueError(f"fraction must lie strictly between 0 and 1 (the last part of the run); got {fraction!r}")
    out = Path(out)
    batches = json.loads((out / "plan.json").read_text())["batches"]
    per: dict[str, dict[str, list[tuple[float, float, float]]]] = defaultdict(lambda: defaultdict(list))
    for b, record, z in _finished_curves(out, batches, set_name):
        steps, regret = z["steps"].astype(np.float64), z["cumulative_regret"].astype(np.float64)
        n = steps[-1]
        if horizon is not None and not horizon >= n:
            raise ValueError(f"horizon must be at least the run's {int(n)} steps; got {horizon!r}")
        t0 = int(np.searchsorted(steps, (1 - fraction) * n))
        if t0 >= steps.size - 1:
            raise ValueError(f"fraction {fraction} leaves fewer than two records of {out.name}'s {steps.size}; "
                             "choose a larger fraction")
        for i, m in enumerate(record["members"]):
            k = m["normalized_cumulative_regret"] / m["cumulative_regret"] if m["cumulative_regret"] else 0.0
            rate = (regret[-1, i] - regret[t0, i]) / (n - steps[t0])
            projected = k * (regret[-1, i] + (horizon - n) * rate) / horizon if horizon is not None else math.nan
            per[b["agent"]][m["mdp"]].append((m["normalized_regret_per_step"], k * rate, projected))
    result = {}
    for agent, mdps in per.items():
        means = np.array([np.mean(v, axis=0) for v in mdps.values()])
        result[agent] = LateRegret(*(float(x) for x in means.mean(axis=0)), len(mdps))
    return result


class ComputeTime(NamedTuple):
    """What one (set, agent) of a run folder cost, from its finished batches' rows of ``batches.csv``: ``compile_s``
    seconds compiling (in the call that finished each batch), ``run_s`` seconds of the lockstep loops (over every
    call that ran a part of a batch); ``batches`` and ``members`` finished, of ``planned`` members in the plan;
    ``hosts``, the machines that finished them (sorted)."""

    compile_s: float
    run_s: float
    batches: int
    members: int
    planned: int
    hosts: tuple[str, ...]

    @property
    def hours(self) -> float:
        """``(compile_s + run_s) / 3600``."""
        return (self.compile_s + self.run_s) / 3600


def compute_time(out: str | os.PathLike) -> dict[tuple[str, str], ComputeTime]:
    """``{(set, agent): ComputeTime}`` of a run folder, in the plan's order, every planned pair included (a pair with
    no finished batch has zeros).

    Sums the rows of ``batches.csv`` (which holds exactly the plan's finished batches, a batch run in parts as its
    parts). A call runs one batch at a time, its members sharded over one host device per core, so for a run made by
    one call at a time on one machine (no Ray, no concurrent shards) the sum is its wall time less each call's set-up
    (building the MDPs, the indicator constants).
    """
    out = Path(out)
    batches = json.loads((out / "plan.json").read_text())["batches"]
    planned: dict[tuple[str, str], int] = defaultdict(int)
    for b in batches:
        planned[(b["set_name"], b["agent"])] += len(b["members"])
    rows = []
    if (out / "batches.csv").exists():
        with (out / "batches.csv").open(newline="") as f:
            rows = list(csv.DictReader(f))
    done: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for r in rows:
        done[(r["set"], r["agent"])].append(r)
    result = {}
    for pair, n in planned.items():
        got = done.get(pair, [])
        result[pair] = ComputeTime(
            compile_s=math.fsum(float(r["compile_s"]) for r in got), run_s=math.fsum(float(r["run_s"]) for r in got),
            batches=len(got), members=sum(int(r["members"]) for r in got), planned=n,
            hosts=tuple(sorted({r.get("host") or "?" for r in got})))
    return result


def compute_table(out: str | os.PathLike) -> str:
    """The report's *Compute* table (Markdown) of :func:`compute_time`: hours per (set, agent) and their total."""
    times = compute_time(out)
    total = ComputeTime(**{f: sum(getattr(t, f) for t in times.values()) for f in ComputeTime._fields if f != "hosts"},
                        hosts=())

    def row(first: str, agent: str, t: ComputeTime, hours: str) -> list[str]:
        return [first, agent, str(t.batches), f"{t.members}/{t.planned}", f"{t.compile_s / 3600:.2f}",
                f"{t.run_s / 3600:.2f}", hours, ", ".join(t.hosts)]

    rows = [row(s, a, t, f"{t.hours:.2f}") for (s, a), t in times.items()]
    rows.append(row("**total**", "", total, f"**{total.hours:.2f}**"))
    header = ["set", "agent", "batches", "members", "compiling, h", "running, h", "total, h", "hosts"]
    return "\n".join(_markdown(header, rows))


def _from_origin(d: dict[str, np.ndarray], column: str) -> tuple[np.ndarray, np.ndarray]:
    """Steps and the mean over seeds of ``column``, starting from ``(0, 0)`` (no regret before the first step)."""
    return np.concatenate([[0], d["steps"]]), np.concatenate([[0.0], d[column].mean(axis=0)])


def curves_figure(s: Summary, set_name: str) -> Any:
    """Cumulative regret against steps, one panel per MDP (module docstring)."""
    from matplotlib.figure import Figure

    labels, agents = s.labels(set_name), s.agents(set_name)
    data = _curves(s, set_name)
    display = _display_labels([i.label for i in sets.instances(set_name)])
    ncols = min(5, len(labels))
    nrows = -(-len(labels) // ncols)
    fig = Figure(figsize=(3.0 * ncols, 2.4 * nrows + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    learners = [a for a in agents if _is_learning(a)]
    random_agent = next((a for a in agents if not _is_learning(a)), None)
    for ax, label in zip(axes, labels):
        for a in learners:
            d = data.get((label, a))
            if d is not None:
                ax.plot(*_from_origin(d, "cumulative_regret"), label=a)
        d = data.get((label, random_agent)) if random_agent else None
        if d is not None:
            ax.plot(*_from_origin(d, "cumulative_regret"), "k--", label=f"{random_agent}")
        else:
            d = next((data[(label, a)] for a in agents if (label, a) in data), None)
            if d is not None:
                ax.plot(*_from_origin(d, "random_cumulative_regret"), "k:", label="uniform policy (exact)")
        ax.set_title(display[label], fontsize=9)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for ax in axes[len(labels):]:
        ax.set_visible(False)
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncols=len(names), fontsize=8)
    fig.suptitle(f"Cumulative regret, {set_name} (mean over {s.n_seeds} seeds)", fontsize=10)
    return fig


def hardness_measures(s: Summary, set_name: str) -> dict[str, tuple[float, float]]:
    """``{mdp: (diameter, value norm)}``, the mean over the run's first :data:`MEASURE_SEEDS` seeds, from
    ``measures.csv`` or computed (:func:`hardness.measures_many`) and cached there."""
    path = s.out / "measures.csv"
    seeds = [int(x) for x in s.settings["seeds"][:MEASURE_SEEDS]]
    cached: dict[tuple[str, str, int], tuple[float, float]] = {}
    if path.exists():
        with path.open(newline="") as f:
            for r in csv.DictReader(f):
                cached[(r["set"], r["mdp"], int(r["seed"]))] = (float(r["diameter"]), float(r["value_norm"]))
    found = [i for i in sets.instances(set_name) if i.label in set(s.labels(set_name))]
    missing = [(i, seed) for i in found for seed in seeds if (set_name, i.label, seed) not in cached]
    if missing:
        import hardness

        m = hardness.measures_many([i.build(seed) for i, seed in missing], variant=MEASURE_VARIANT)
        for k, (i, seed) in enumerate(missing):
            cached[(set_name, i.label, seed)] = (float(m.diameter.value[k]), float(m.value_norm.value[k]))
        tmp = path.with_name(path.name + ".tmp")
        with tmp.open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["set", "mdp", "seed", "diameter", "value_norm"])  # variant: MEASURE_VARIANT
            w.writerows([k[0], k[1], k[2], f"{v[0]:.9g}", f"{v[1]:.9g}"] for k, v in sorted(cached.items()))
        os.replace(tmp, path)
    return {i.label: tuple(np.mean([cached[(set_name, i.label, seed)] for seed in seeds], axis=0)) for i in found}


def hardness_figure(s: Summary, set_name: str) -> Any:
    """Diameter x value norm of every MDP, coloured by each learning agent's mean regret (§3.3, Figure 2)."""
    from matplotlib.figure import Figure

    measures = hardness_measures(s, set_name)
    learners = [a for a in s.agents(set_name) if _is_learning(a)] or s.agents(set_name)
    fig = Figure(figsize=(3.6 * len(learners) + 0.8, 3.4), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(learners), squeeze=False)).ravel()
    labels = s.labels(set_name)
    x = np.array([measures[lab][0] for lab in labels])
    y = np.array([measures[lab][1] for lab in labels])
    sc = None
    for ax, a in zip(axes, learners):
        c = np.array([(s.cell(set_name, lab, a) or (math.nan,))[0] for lab in labels])
        ok = np.isfinite(c)
        sc = ax.scatter(x[ok], y[ok], c=c[ok], cmap="viridis", vmin=0.0, vmax=1.0, s=36, edgecolors="k",
                        linewidths=0.4)
        ax.scatter(x[~ok], y[~ok], facecolors="none", edgecolors="0.6", s=36)
        ax.set_title(a, fontsize=9)
        ax.set_xlabel(f"Diameter ({MEASURE_VARIANT})", fontsize=8)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
    axes[0].set_ylabel("Environmental value norm", fontsize=8)
    if sc is not None:
        fig.colorbar(sc, ax=list(axes), label="normalised regret per step")
    fig.suptitle(f"Hardness and regret, {set_name}", fontsize=10)
    return fig


def _paper_source(emission: str | None) -> str:
    """What the *(paper)* columns hold for a run of ``emission`` (``None``: the agents observed the states)."""
    if emission is None:
        return "; *(paper)*: the paper's Table 2 (500 000 steps, 20 seeds, runs cut off after 10 minutes)."
    if emission == published.NONTABULAR_EMISSION:
        return ("; *(paper)*: App. G's non-tabular table (the `StateInfo` emission, 500 000 steps, 20 seeds, runs cut "
                "off after 40 minutes).")
    return f"; the paper has no numbers for agents observing the `{emission}` emission."


def _beside_text(s: Summary) -> list[str]:
    """The report's paragraph on where the columns come from: the run's own registered agents' hyperparameters, the
    baseline's folders and the agents it left out."""
    from hardness.benchmark import hparams as hp_sources

    import agents as agent_registry

    lines = []
    own = dict.fromkeys(a for agents in s.settings["agents"].values() for a in agents)
    for a in own:
        if a not in agent_registry.SHIPPED:  # your own agent: its values, and where they came from when known here
            values = ", ".join(f"{k}={v}" for k, v in s.settings["hparams"].get(a, {}).items())
            source = (f", {hp_sources.source_of(a, s.settings['hparams_source'])}" if a in agent_registry.AGENTS
                      else "")
            lines.append(f"Hyperparameters of `{a}`: {values or 'none'}{source}.")
    b = s.beside
    if b is not None:
        origins = sorted(set(b.origin.values()))
        lines.append(f"Columns marked ({b.label}): {b.description}, made under this run's protocol (steps, seeds, "
                     f"log period, emission, agent rules, indicators and the hyperparameters that `--hparams "
                     f"{s.settings['hparams_source']}` gives them), from {', '.join(f'`{o}`' for o in origins)}; "
                     "they were not run again (their random streams are those of their own runs, so their numbers "
                     "are statistically, not bitwise, those of a run here).")
        if b.left_out:
            lines.append("Not set beside this run (their protocol differs): " + "; ".join(
                f"{a} in {st} ({', '.join(d)})" for (st, a), d in b.left_out.items()) + ".")
    return [" ".join(lines), ""] if lines else []


def write_report(out: str | os.PathLike, baseline: str | os.PathLike | None = None) -> list[Path]:
    """Write ``report.md``, ``report.tex`` and the figures into the run folder ``out`` (module docstring), with
    ``baseline``'s comparable results beside the run's own (``"committed"`` or a run folder; ``None``: none); returns
    the files written."""
    s = summarize(out, baseline)
    written = []
    stop = ", with the reference's convergence stop" if s.settings.get("stop_when_converged") else ""
    md = [
        "# Benchmark report",
        "",
        f"{s.n_steps:,} steps per run, seeds {', '.join(map(str, s.settings['seeds']))}, indicators every "
        f"{', '.join(f'{v} ({k})' for k, v in s.settings['log_periods'].items())} steps, hyperparameters: "
        f"{s.settings['hparams_source']}, agent rules: {s.settings.get('agent_variant', 'paper')} (colosseum: "
        f"reference mode), indicators: {s.settings.get('variant', 'paper')} (colosseum: the reference's){stop}. "
        "Every run completed its steps (no wall-clock cut-off). Score: final "
        "`normalized_cumulative_regret` / steps (App. E), mean ± std over seeds; bold: the lowest learning agent per "
        f"row{_paper_source(s.settings.get('emission'))}",
        "",
        *_beside_text(s),
    ]
    tex = []
    for set_name in s.settings["sets"]:
        stem = s.out / sets.canonical_name(set_name).replace(" ", "_")
        curves = _save(curves_figure(s, set_name), stem.with_name(f"curves_{stem.name}"))
        hard = _save(hardness_figure(s, set_name), stem.with_name(f"hardness_{stem.name}"))
        written += curves + hard
        md += [f"## {set_name}", "", markdown_table(s, set_name), "", "### Per MDP and agent (App. G)", ""]
        md += _markdown(*_appendix_rows(s, set_name, latex=False))
        md += ["", f"![cumulative regret]({curves[0].name})", "", f"![hardness and regret]({hard[0].name})", ""]
        tex.append(latex_table(s, set_name))
        caption = f"Final performance indicators, {set_name}."
        tex.append("\n".join(_latex(*_appendix_rows(s, set_name, latex=True), caption)))
    if s.members:
        md += ["## Aggregates across MDPs", "",
               "Interquartile mean and mean of the per-step normalised regret pooled over seeds and MDPs, with "
               "stratified-bootstrap intervals (`hardness.benchmark.aggregate`; Agarwal et al. 2021).", "",
               aggregate.aggregate_table(s.members)]
    md += ["", "## Compute", "",
           "Hours of the finished batches, summed from `batches.csv` (`hardness.benchmark.report.compute_time`): "
           "compiling, and the lockstep loops over every call that ran a part of a batch. A call runs one batch at a "
           "time on all of a machine's cores, so for a run made by one call at a time on one machine (no Ray, no "
           "concurrent shards) the total is its wall time less each call's set-up.", "", compute_table(s.out)]
    (s.out / "report.md").write_text("\n".join(md) + "\n")
    (s.out / "report.tex").write_text("\n".join(tex) + "\n")
    return [s.out / "report.md", s.out / "report.tex"] + written
