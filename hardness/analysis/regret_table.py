"""Normalised cumulative regret of every tabular agent beside the random agent's, on small RiverSwim and DeepSea.

Every episodic agent (``random_episodic``, ``q_learning_episodic``, ``psrl_episodic``) runs on the episodic versions
and every continuous agent (``random_continuous``, ``q_learning_continuous``, ``psrl_continuous``, ``ucrl2``) on the
continuous versions of the chosen instances, for ``--steps`` steps and ``--seeds`` seeds (0, 1, ...), with the
agents' default (benchmark-tuned) hyperparameters. An agent's whole grid, MDPs x seeds, is one
:func:`jaxmdp.experiment.runner.run` call (one lockstep program, the MDPs padded to common shapes).

The score is the paper's (Table 2, App. E; docs/benchmark.md §2): the ``normalized_cumulative_regret`` of the last
record divided by the number of steps, i.e. the per-step normalised regret ``(rho* - rho^pi_t) / (rho* - rho^-)``
averaged over the run (continuous; episodic: the episode regret over ``V*_0 - V^-_0``), 0 for an optimal agent and 1 for
the worst policy. The table gives its mean and 95% confidence interval over seeds (Student t), and the raw
``cumulative_regret`` after the last step likewise. Indicators are exact policy evaluations every ``--log-period`` steps
(100, as the reference); learning never stops (no wall-clock budget, unlike the reference's 10 minutes).

Instances (``--families``; ``--sizes``, for every family or per family; the same parameters in both settings):

* RiverSwim: ``p_lazy = 0.1``, ``p_rand = 0.01``, Beta rewards (``make_reward_stochastic``), actions not permuted
  (the episodic-ergodic benchmark's RiverSwim ``prms_0`` is this instance at size 5);
* DeepSea: no ``p_rand``, Beta rewards, actions not permuted (the episodic-communicating benchmark's DeepSea
  ``prms_0`` is this instance at size 5).

Output in ``--out`` (default ``results/regret_table``):

* ``runs/<agent>-<hash of the settings>.csv``: the runner's CSV (every record of every member, the reference's
  columns), written chunk by chunk; ``.npz``: the runner's checkpoint, so an interrupted agent resumes where it
  stopped; ``.json``: the finished agent's final values per member (an agent with one is not run again);
* ``regret_table.md`` / ``regret_table.csv``: the table (one row per agent and MDP), rewritten after every agent;
  ``regret_table_members.csv``: the final values of every member.

The tables list every agent finished with the same settings in ``--out``, also those of earlier invocations (so
agents can be run one at a time); an invocation reuses everything finished. Progress goes to stderr.

    jaxmdp-regret-table       # 100k steps, 20 seeds, RiverSwim 5 and 10, DeepSea 5
    jaxmdp-regret-table --families DeepSea --sizes 10 --out results/regret_table_deepsea10
    jaxmdp-regret-table --steps 20000 --agents ucrl2 random_continuous --sizes 5
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import json
import math
import os
import platform
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np
from scipy import stats  # the Student-t quantile and the standard error of the mean

import agents
import jaxmdp
from agents import psrl_continuous
from jaxmdp.experiment import records, runner

EPISODIC_AGENTS = ("random_episodic", "q_learning_episodic", "psrl_episodic")
CONTINUOUS_AGENTS = ("random_continuous", "q_learning_continuous", "psrl_continuous", "ucrl2")
ALL_AGENTS = EPISODIC_AGENTS + CONTINUOUS_AGENTS
RANDOM = {True: "random_episodic", False: "random_continuous"}

#: The instances' parameters besides ``size`` (module docstring).
FAMILY_PARAMS: dict[str, dict[str, Any]] = {
    "RiverSwim": dict(p_lazy=0.1, p_rand=0.01, make_reward_stochastic=True, randomize_actions=False),
    "DeepSea": dict(p_rand=None, make_reward_stochastic=True, randomize_actions=False),
}

#: The paper's Table 2 numbers (benchmark, 500k steps) for each agent on RiverSwim and DeepSea (sizes in brackets;
#: ``p_rand`` noted where the instance has one), and up to which size of this script's instances they put the agent
#: far below the random agent (``None``: on no comparable instance). Comparable means the same noise regime:
#: RiverSwim with ``p_lazy`` and a small ``p_rand``, DeepSea without ``p_rand`` (a ``p_rand`` of .1-.4 makes DeepSea's
#: exploration easy, so the small numbers of those instances are not a guide here). Two benchmark MDPs are exactly
#: this script's instances: episodic-ergodic RiverSwim ``prms_0`` = RiverSwim-5 episodic and episodic-communicating
#: DeepSea ``prms_0`` = DeepSea-5 episodic.
PAPER: dict[tuple[str, str], tuple[str, int | None]] = {
    ("psrl_episodic", "RiverSwim"): (".00 (5, 25, 30); .80 (40, deterministic)", 30),
    ("psrl_episodic", "DeepSea"): (".00 (5), .54 (25); .00-.01 (10-13, p_rand .3-.4)", 5),
    ("q_learning_episodic", "RiverSwim"): (".07 (5), .87 (25), .91 (30)", 5),
    ("q_learning_episodic", "DeepSea"): (".01 (5), .83 (25); .52-.64 (10-13, p_rand .3-.4)", 5),
    ("psrl_continuous", "RiverSwim"): (".00-.02 (25-90)", 90),
    ("psrl_continuous", "DeepSea"): (".78-.99 (35-40); .06 (20, p_rand .1)", None),
    ("ucrl2", "RiverSwim"): (".00-.02 (25-90)", 90),
    ("ucrl2", "DeepSea"): (".90-.99 (35-40); .23 (20, p_rand .1)", None),
    ("q_learning_continuous", "RiverSwim"): (".16-.34 (25, 90); .50-.90 (30-80, p_rand .01-.2)", None),
    ("q_learning_continuous", "DeepSea"): (".78-.99 (35-40); .94 (20, p_rand .1)", None),
}


def paper_expectation(agent: str, mdp: str) -> tuple[str, bool]:
    """``(the paper's numbers, whether the agent should beat random clearly on mdp)`` for a short name
    ``Family-size``."""
    family, _, size = mdp.rpartition("-")
    text, up_to = PAPER.get((agent, family), ("", None))
    return text, up_to is not None and int(size) <= up_to


#: Default sizes: small enough for a CPU; DeepSea 10 (S = 55) would pad every member of the planning agents' lockstep
#: grids to 55 states, which makes them far slower.
DEFAULT_SIZES = {"RiverSwim": (5, 10), "DeepSea": (5,)}

MEMBER_FIELDS = ("mdp", "seed", "normalized_regret_per_step", "cumulative_regret", "random_normalized_regret_per_step")


# ---------------------------------------------------------------------------------------------------------------
# Statistics
# ---------------------------------------------------------------------------------------------------------------


def mean_ci(x: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    """Mean and half-width ``t_{(1+level)/2, n-1} s / sqrt(n)`` of the two-sided ``level`` Student-t confidence
    interval of the mean of ``n`` samples with standard deviation ``s`` (NaN half-width for one sample)."""
    x = np.asarray(x, np.float64)
    n = x.size
    if n < 2:
        return float(x.mean()), float("nan")
    half = stats.t.ppf(0.5 + level / 2, n - 1) * stats.sem(x)  # sem: s / sqrt(n), s with ddof = 1
    return float(x.mean()), float(half)


# ---------------------------------------------------------------------------------------------------------------
# Instances and runs
# ---------------------------------------------------------------------------------------------------------------


def parse_sizes(items: Sequence[str] | None, families: Sequence[str]) -> dict[str, list[int]]:
    """``--sizes``: integers (every family at every size) or ``FAMILY=5,10`` items (one per family); ``None``:
    :data:`DEFAULT_SIZES`."""
    if items is None:
        return {f: list(DEFAULT_SIZES[f]) for f in families}
    items = [str(x) for x in items]
    try:
        if all("=" not in x for x in items):
            sizes = [int(x) for x in items]
            out = {f: sizes for f in families}
        else:
            out = {}
            for item in items:
                fam, sep, values = item.partition("=")
                if not sep or fam not in families:
                    raise ValueError(f"--sizes item {item!r} must be FAMILY=5,10 with FAMILY among {list(families)}")
                out[fam] = [int(v) for v in values.split(",")]
            if set(out) != set(families):
                raise ValueError(f"--sizes must give sizes for every family of --families {list(families)}")
    except ValueError as err:
        raise SystemExit(f"regret_table: {err}") from None
    if any(v < 2 for vs in out.values() for v in vs):
        raise SystemExit("regret_table: sizes must be integers >= 2")
    return {f: out[f] for f in families}


def build_mdps(sizes: dict[str, Sequence[int]], episodic: bool) -> tuple[list[jaxmdp.MDP], list[str]]:
    """Every family at each of its sizes (seed 0; RiverSwim and DeepSea do not depend on the seed) and their short
    names (``RiverSwim-5``)."""
    mdps, names = [], []
    for family, family_sizes in sizes.items():
        if family not in FAMILY_PARAMS:
            raise ValueError(f"families must be among {sorted(FAMILY_PARAMS)}; got {family!r}")
        for size in family_sizes:
            mdps.append(jaxmdp.make(family, episodic=episodic, seed=0, size=int(size), **FAMILY_PARAMS[family]))
            names.append(f"{family}-{int(size)}")
    return mdps, names


def hparams_for(name: str, mdps: Sequence[jaxmdp.MDP]) -> Any:
    """The agent's default hyperparameters. PSRL continuous's static candidate buffer ``max_psi`` (default 60) is
    sized to the largest ``psi`` of the grid: its docstring's advice, and results do not change while
    ``max_psi >= psi``; only memory and the planner's action count shrink."""
    agent = agents.get(name)
    hp = agent.default_hparams
    if name == "psrl_continuous":
        need = max(psrl_continuous.psi(hp, int(np.sum(m.state_mask)), int(np.sum(m.action_mask))) for m in mdps)
        hp = hp.replace(max_psi=min(hp.max_psi, need))
    return hp


@dataclasses.dataclass
class AgentRun:
    """The final values of one agent's grid (one entry per member, MDP-major then seed)."""

    agent: str
    episodic: bool
    mdp_labels: list[str]  # short names (RiverSwim-5), in the grid's MDP order
    members: list[dict]
    compile_s: float
    run_s: float
    n_members: int
    n_steps: int
    agent_steps_per_second: float
    config: dict

    def to_json(self) -> dict:
        return dataclasses.asdict(self)


def final_members(result: runner.RunResult, mdp_names: Sequence[str]) -> list[dict]:
    """One dict per member: its MDP's name (``mdp_names[i]`` for the grid's MDP ``i``), seed and the last record's
    regret columns (the score divided by steps)."""
    if result.steps.size == 0 or int(result.steps[-1]) != result.n_steps:
        raise RuntimeError("the run did not reach its last step")
    n = float(result.n_steps)
    norm = result.column("normalized_cumulative_regret")[-1]
    raw = result.column("cumulative_regret")[-1]
    rnd = result.column("random_normalized_cumulative_regret")[-1]
    g = result.grid
    return [
        dict(
            mdp=mdp_names[g.mdp_index[b]],
            seed=int(g.seeds[b]),
            normalized_regret_per_step=float(norm[b] / n),
            cumulative_regret=float(raw[b]),
            random_normalized_regret_per_step=float(rnd[b] / n),
        )
        for b in range(g.n_members)
    ]


def run_stem(name: str, config: dict) -> str:
    """``<agent>-<hash of the settings>``: runs of different settings keep different files."""
    digest = hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:10]
    return f"{name}-{digest}"


def load_run(run_dir: Path, name: str, config: dict) -> AgentRun | None:
    """The finished run of agent ``name`` in ``run_dir`` if its settings are ``config`` (plus the agent's name)."""
    summary = run_dir / f"{run_stem(name, config)}.json"
    if summary.exists():
        saved = json.loads(summary.read_text())
        if saved.get("config") == {**config, "agent": name}:
            return AgentRun(**saved)
    return None


def finished_runs(run_dir: Path, config: dict) -> list[AgentRun]:
    """Every agent with a finished run of these settings in ``run_dir`` (also those run by earlier invocations with
    other ``--agents``), in the order of :data:`ALL_AGENTS`."""
    return [r for r in (load_run(run_dir, n, config) for n in ALL_AGENTS) if r is not None]


def run_agent(
    name: str,
    mdps: Sequence[jaxmdp.MDP],
    mdp_names: Sequence[str],
    seeds: Sequence[int],
    n_steps: int,
    log_period: int,
    run_dir: Path,
    settings: dict,
    progress: bool = True,
) -> tuple[AgentRun, runner.RunResult | None]:
    """Run (or resume, or reuse) one agent on its grid with ``settings`` (the table's, without the agent); returns
    its final values and the runner's result (``None`` when the finished run was reused from its ``.json``)."""
    stem = run_stem(name, settings)
    summary = run_dir / f"{stem}.json"
    done = load_run(run_dir, name, settings)
    if done is not None:
        return done, None
    agent = agents.get(name)
    hp = hparams_for(name, mdps)
    grid = runner.product(list(mdps), [hp], seeds)
    result = runner.run(
        agent, grid, n_steps, log_period=log_period, csv_path=run_dir / f"{stem}.csv",
        checkpoint_path=run_dir / f"{stem}.npz", progress=progress,
    )
    out = AgentRun(
        agent=name,
        episodic=agent.episodic,
        mdp_labels=list(mdp_names),
        members=final_members(result, mdp_names),
        compile_s=result.compile_s,
        run_s=result.run_s,
        n_members=grid.n_members,
        n_steps=n_steps,
        agent_steps_per_second=result.agent_steps_per_second,
        config={**settings, "agent": name},
    )
    tmp = summary.with_name(summary.name + ".tmp")
    tmp.write_text(json.dumps(out.to_json(), indent=1))
    os.replace(tmp, summary)
    return out, result


# ---------------------------------------------------------------------------------------------------------------
# Table
# ---------------------------------------------------------------------------------------------------------------

TABLE_COLUMNS = (
    "setting", "agent", "mdp", "n_seeds", "n_steps",
    "normalized_regret_per_step_mean", "normalized_regret_per_step_ci95",
    "cumulative_regret_mean", "cumulative_regret_ci95",
    "random_baseline_normalized_regret_per_step",
    "grid_compile_s", "grid_run_s", "run_s_per_member", "agent_steps_per_second",
)


def table_rows(runs: Sequence[AgentRun]) -> list[dict]:
    """One row per (agent, MDP): mean and 95% CI over seeds of the score and of the raw cumulative regret."""
    rows = []
    for r in runs:
        for label in r.mdp_labels:
            ms = [m for m in r.members if m["mdp"] == label]
            norm_mean, norm_ci = mean_ci(np.array([m["normalized_regret_per_step"] for m in ms]))
            raw_mean, raw_ci = mean_ci(np.array([m["cumulative_regret"] for m in ms]))
            rows.append(dict(
                setting="episodic" if r.episodic else "continuous",
                agent=r.agent,
                mdp=label,
                n_seeds=len(ms),
                n_steps=r.n_steps,
                normalized_regret_per_step_mean=norm_mean,
                normalized_regret_per_step_ci95=norm_ci,
                cumulative_regret_mean=raw_mean,
                cumulative_regret_ci95=raw_ci,
                random_baseline_normalized_regret_per_step=ms[0]["random_normalized_regret_per_step"],
                grid_compile_s=r.compile_s,
                grid_run_s=r.run_s,
                run_s_per_member=r.run_s / r.n_members,
                agent_steps_per_second=r.agent_steps_per_second,
            ))
    return rows


def verdicts(rows: Sequence[dict]) -> list[dict]:
    """For every non-random agent and MDP: does it beat the random agent clearly? "Clearly": the upper end of its
    95% interval lies below the lower end of the random agent's and its mean is at most half the random agent's."""
    by_key = {(r["setting"], r["agent"], r["mdp"]): r for r in rows}
    out = []
    for r in rows:
        if r["agent"].startswith("random"):
            continue
        base = by_key.get((r["setting"], RANDOM[r["setting"] == "episodic"], r["mdp"]))
        if base is None:
            continue
        ci = lambda x: 0.0 if math.isnan(x) else x  # noqa: E731
        mean, base_mean = r["normalized_regret_per_step_mean"], base["normalized_regret_per_step_mean"]
        upper = mean + ci(r["normalized_regret_per_step_ci95"])
        lower = base_mean - ci(base["normalized_regret_per_step_ci95"])
        paper, expected = paper_expectation(r["agent"], r["mdp"])
        out.append(dict(setting=r["setting"], agent=r["agent"], mdp=r["mdp"],
                        beats_random_clearly=upper < lower and mean <= 0.5 * base_mean,
                        paper=paper, expected=expected, ratio=mean / base_mean))
    return out


def _agent_table(cell: dict, names: Sequence[str], mdps: Sequence[str], score: str, digits: int) -> list[str]:
    """Markdown rows ``mean ± CI half-width`` (the mean alone where the CI is NaN: one seed) of ``score``, one per
    agent, one column per MDP."""
    def fmt(r: dict) -> str:
        mean, ci = r[f"{score}_mean"], r[f"{score}_ci95"]
        return f"{mean:.{digits}f}" if math.isnan(ci) else f"{mean:.{digits}f} ± {ci:.{digits}f}"

    lines = ["| agent | " + " | ".join(mdps) + " |", "|---|" + "---|" * len(mdps)]
    for name in names:
        lines.append(f"| {name} | " + " | ".join(fmt(cell[name, m]) if (name, m) in cell else "" for m in mdps)
                     + " |")
    return lines


def markdown(rows: Sequence[dict], runs: Sequence[AgentRun], settings: dict) -> str:
    """The report: per setting, agent x MDP tables of the score and of the raw regret, compute, verdicts."""
    lines = [
        "# Normalised cumulative regret of the tabular agents beside the random agent",
        "",
        f"{settings['n_steps']:,} steps, seeds 0-{settings['n_seeds'] - 1} ({settings['n_seeds']} seeds), indicators "
        f"every {settings['log_period']} steps (exact policy evaluation), default (tuned) hyperparameters, "
        "`variant=\"paper\"`. Generated by `jaxmdp-regret-table`.",
        "",
        "Score (the paper's Table 2 number, App. E): final `normalized_cumulative_regret` / steps, mean ± 95% CI "
        "(Student t) over seeds; 0 = optimal, 1 = worst policy. *Random baseline* is the uniform policy's exact "
        "per-step normalised regret (the random agent must match it).",
        "",
        "Instances: " + "; ".join(f"{fam} sizes {', '.join(map(str, sizes))} with {FAMILY_PARAMS[fam]}"
                                  for fam, sizes in settings["sizes"].items()) + ".",
        "",
    ]
    for setting in ("episodic", "continuous"):
        srows = [r for r in rows if r["setting"] == setting]
        if not srows:
            continue
        mdps = list(dict.fromkeys(r["mdp"] for r in srows))
        names = list(dict.fromkeys(r["agent"] for r in srows))
        cell = {(r["agent"], r["mdp"]): r for r in srows}
        base = {r["mdp"]: r["random_baseline_normalized_regret_per_step"] for r in srows}
        lines += [f"## {setting.capitalize()}", "", "### Normalised cumulative regret per step", ""]
        lines += _agent_table(cell, names, mdps, "normalized_regret_per_step", 3)
        lines.append("| *random baseline (exact)* | " + " | ".join(f"{base[m]:.3f}" for m in mdps) + " |")
        lines += ["", "### Cumulative regret (raw, after the last step)", ""]
        lines += _agent_table(cell, names, mdps, "cumulative_regret", 1)
        lines.append("")
    lines += [
        "## Compute",
        "",
        "One runner call per agent (all MDPs x seeds in lockstep); `run s` excludes compilation; *s per run* is the "
        "grid's run time divided by its members (lockstep amortises it); agent-steps/s counts every member's steps.",
        "",
        "| agent | members | compile s | run s | s per run | agent-steps/s |",
        "|---|---|---|---|---|---|",
    ]
    for r in runs:
        lines.append(f"| {r.agent} | {r.n_members} | {r.compile_s:.1f} | {r.run_s:.1f} | {r.run_s / r.n_members:.2f} | "
                     f"{r.agent_steps_per_second:,.0f} |")
    compute = sum(r.compile_s + r.run_s for r in runs)
    lines += ["", f"Compile + run time summed over the agents: {compute:.0f} s ({compute / 60:.1f} min) on "
              f"{settings['machine']}, shared with other jobs (timings are noisy).", ""]
    v = verdicts(rows)
    if v:
        lines += [
            "## Against the random agent",
            "",
            "*Clearly better*: the agent's 95% CI lies below the random agent's and its mean is at most half of it. "
            "*Paper*: the agent's Table 2 numbers on the family (500k steps, 5x this table's; sizes in brackets; the "
            "episodic RiverSwim 5 and DeepSea 5 of the benchmark are exactly the instances here). *Expected*: the "
            "paper has the agent far below random on a comparable instance (same noise regime) of this size or "
            "larger.",
            "",
            "| setting | agent | MDP | mean / random | clearly better | expected | paper (Table 2) |",
            "|---|---|---|---|---|---|---|",
        ]
        for x in v:
            flag = "yes" if x["beats_random_clearly"] else ("**NO**" if x["expected"] else "no")
            lines.append(f"| {x['setting']} | {x['agent']} | {x['mdp']} | {x['ratio']:.3f} | {flag} | "
                         f"{'yes' if x['expected'] else ''} | {x['paper']} |")
        lines.append("")
    return "\n".join(lines)


def _write_csv(path: Path, header: Sequence[str], rows: Sequence[list]) -> None:
    """A CSV in the runner's number format (:func:`jaxmdp.experiment.records.format_row`: floats to 9 significant
    digits)."""
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(records.format_row(r) for r in rows)


def write_outputs(out: Path, runs: Sequence[AgentRun], settings: dict) -> list[dict]:
    """Write the table (markdown and CSV) and the per-member CSV; returns the table rows."""
    rows = table_rows(runs)
    _write_csv(out / "regret_table.csv", TABLE_COLUMNS, [[r[c] for c in TABLE_COLUMNS] for r in rows])
    _write_csv(out / "regret_table_members.csv", ("setting", "agent") + MEMBER_FIELDS,
               [["episodic" if r.episodic else "continuous", r.agent] + [m[k] for k in MEMBER_FIELDS]
                for r in runs for m in r.members])
    (out / "regret_table.md").write_text(markdown(rows, runs, settings))
    return rows


# ---------------------------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------------------------


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer; got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--steps", type=_positive, default=100_000, help="steps per run (default %(default)s)")
    p.add_argument("--seeds", type=_positive, default=20, help="number of seeds, 0..N-1 (default %(default)s)")
    p.add_argument("--families", nargs="+", default=list(FAMILY_PARAMS), choices=list(FAMILY_PARAMS),
                   help="default %(default)s")
    p.add_argument("--sizes", nargs="+", default=None,
                   help="sizes of every family, or FAMILY=5,10 items, one per family (default: RiverSwim=5,10 "
                        "DeepSea=5)")
    p.add_argument("--agents", nargs="+", default=list(ALL_AGENTS), choices=list(ALL_AGENTS),
                   help="default: all seven")
    p.add_argument("--out", type=Path, default=Path("results/regret_table"), help="default %(default)s")
    p.add_argument("--log-period", type=_positive, default=100, help="steps between indicator logs (%(default)s)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return p


def main(argv: Sequence[str] | None = None) -> dict:
    """Run the table (module docstring); returns ``{"rows", "runs", "results"}`` (``results``: the runner's results
    of the agents run by this call, by name)."""
    return run_table(build_parser().parse_args(argv))


def run_table(args: argparse.Namespace) -> dict:
    """:func:`main` on parsed arguments (the console command adds its own options to :func:`build_parser`)."""
    out = args.out
    run_dir = out / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    seeds = list(range(args.seeds))
    settings = dict(
        n_steps=args.steps, n_seeds=args.seeds, log_period=args.log_period, families=list(args.families),
        sizes=parse_sizes(args.sizes, args.families), machine=f"{platform.machine()}, {os.cpu_count()} cores, "
        f"{jax.local_device_count()} JAX {jax.default_backend()} device(s)",
    )
    config = {k: settings[k] for k in ("n_steps", "n_seeds", "log_period", "families", "sizes")}
    mdps = {ep: build_mdps(settings["sizes"], ep) for ep in (True, False)}
    names = [n for n in ALL_AGENTS if n in args.agents]  # settings grouped, random first
    results = {}
    for i, name in enumerate(names):
        agent = agents.get(name)
        if not args.quiet:
            print(f"[{i + 1}/{len(names)}] {name}: {len(mdps[agent.episodic][0])} MDPs x {len(seeds)} seeds, "
                  f"{args.steps} steps", file=sys.stderr, flush=True)
        run, result = run_agent(name, *mdps[agent.episodic], seeds, args.steps, args.log_period, run_dir,
                                config, progress=not args.quiet)
        if result is not None:
            results[name] = result
        if not args.quiet:
            state = "reused" if result is None else f"compile {run.compile_s:.1f} s, run {run.run_s:.1f} s"
            print(f"    {name}: {state}, {run.agent_steps_per_second:,.0f} agent-steps/s", file=sys.stderr,
                  flush=True)
        runs = finished_runs(run_dir, config)  # the table after every agent, so an interruption keeps it
        rows = write_outputs(out, runs, settings)
    if not args.quiet:
        print(f"wrote {out / 'regret_table.md'} and {out / 'regret_table.csv'}", file=sys.stderr)
    return {"rows": rows, "runs": runs, "results": results}

