"""The sweep command line (paper §3.2, App. D): ``jaxmdp-sweep --scenario {1,2,3,4}`` and its scenario-1 alias
``jaxmdp-sweep-prand`` (:mod:`hardness.cli.sweep`).

A run computes one scenario of :mod:`hardness.analysis.scenarios` for one family and setting, seed by seed
(``--seeds-per-call`` seeds per batched call), and after every call rewrites, atomically, ``<out>/<stem>.csv``: one row
per finished ``(seed, value)`` with the raw measures, their ``converged`` flags and their App. E normalisation over the
rows written so far (so the final file holds the normalisation over all seeds and values). ``<stem>.json`` records the
settings; ``--resume`` reuses the finished seeds of an earlier run with the same settings and computes only the others.
At the end ``<stem>.png`` shows the normalised measures against the swept parameter (mean over seeds, 95% bootstrap
band). Progress goes to stderr, as a bar on a terminal (:mod:`jaxmdp.experiment.progress`: seeds done, time left),
the paths written to stdout.

``--seeds N`` runs seeds ``0..N-1`` (default 3: seeds 0, 1, 2), as in every command of the package;
``--seed-list S [S ...]`` names the seeds one by one instead.
"""

from __future__ import annotations

import argparse
import ast
import csv
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import jaxmdp
from jaxmdp.experiment import compilation
from jaxmdp.experiment.progress import Progress
from hardness.analysis import scenarios
from hardness.analysis.near_optimal import NEAR_OPTIMAL_AGENTS, tuned_regret
from hardness.analysis.plotting import plot_scenario

MEASURES = scenarios.MEASURES
#: Columns of the tuned near-optimal agent (empty when ``--agent-steps 0``): its expected cumulative regret, the
#: per-step normalised version (App. E) and that one min-max normalised over the table (the figure's curve).
AGENT_COLUMNS = ("agent", "agent_cumulative_regret", "agent_normalized_cumulative_regret", "agent_regret_normalized")
COLUMNS = (
    ["scenario", "family", "setting", "variant", "seed", "parameter", "value", "n_states"]
    + list(MEASURES)
    + [f"{m}_converged" for m in MEASURES]
    + [f"{m}_normalized" for m in MEASURES]
    + list(AGENT_COLUMNS)
)
#: Name of the agent curve in the figure (:data:`hardness.analysis.plotting.LABELS`).
AGENT_CURVE = "agent_regret"

DEFAULT_FAMILY = "MiniGridEmpty"
DEFAULT_SETTING = "episodic"
DEFAULT_SEEDS = (0, 1, 2)
#: Output folder of each scenario when ``--out`` is not given.
DEFAULT_OUTS = {1: "results/sweep_prand", 2: "results/sweep_plazy", 3: "results/sweep_size", 4: "results/sweep_size"}
# Tuned near-optimal agent: small defaults so that the main job runs in minutes on a laptop's CPU (the paper: 200 000
# steps, 120 candidates, 3 seeds; hardness.analysis.near_optimal).
DEFAULT_AGENT_STEPS = 10_000
DEFAULT_AGENT_CANDIDATES = 4
DEFAULT_AGENT_TUNING_SEEDS = 1


# ---------------------------------------------------------------------------------------------------------------
# Arguments
# ---------------------------------------------------------------------------------------------------------------


def parse_param(item: str) -> tuple[str, Any]:
    """``key=value`` with ``value`` a Python literal (``10``, ``0.1``, ``True``, ``None``) or else a string."""
    key, sep, value = item.partition("=")
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f"--param must look like key=value; got {item!r}")
    try:
        parsed = ast.literal_eval(value.strip())
    except (ValueError, SyntaxError):
        parsed = value.strip()
    return key.strip(), parsed


def number(text: str) -> int | float:
    """An int when the text is one (sizes), else a float (probabilities)."""
    try:
        return int(text)
    except ValueError:
        try:
            return float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None


def positive(text: str) -> int:
    """A positive integer (``--seeds N``)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer; got {text}")
    return value


def build_parser(description: str, default_out: str | None, scenario_choices: Sequence[int]) -> argparse.ArgumentParser:
    """The sweep's options; ``default_out=None``: the scenario's folder of :data:`DEFAULT_OUTS`."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    if len(scenario_choices) > 1:
        parser.add_argument(
            "--scenario", type=int, choices=list(scenario_choices), default=scenario_choices[0],
            help="1: p_rand; 2: p_lazy; 3: size; 4: size with p_rand = 0.1 (default %(default)s)",
        )
    parser.add_argument("--family", default=DEFAULT_FAMILY, choices=jaxmdp.families(), help="default %(default)s")
    parser.add_argument("--setting", default=DEFAULT_SETTING, choices=["episodic", "continuous"],
                        help="default %(default)s")
    parser.add_argument("--values", type=number, nargs="+", default=None,
                        help="grid of the swept parameter (default: the family's defaults in "
                             "hardness.analysis.scenarios)")
    parser.add_argument("--seeds", type=positive, default=len(DEFAULT_SEEDS),
                        help="number of seeds, 0..N-1 (default %(default)s)")
    parser.add_argument("--seed-list", type=int, nargs="+", default=None, metavar="SEED",
                        help="these seeds instead of 0..N-1")
    parser.add_argument("--param", type=parse_param, action="append", default=[], metavar="KEY=VALUE",
                        help="family parameter, repeatable; replaces the family default of that key")
    parser.add_argument("--variant", choices=["paper", "colosseum"], default="paper", help="default %(default)s")
    parser.add_argument("--gamma", type=float, default=0.99, help="discount of value norm and gap sum (%(default)s)")
    parser.add_argument("--seeds-per-call", type=int, default=1,
                        help="seeds computed per batched call, i.e. between two writes (default %(default)s)")
    out_help = "output folder (default %(default)s)" if default_out else \
        "output folder (default: results/sweep_prand, sweep_plazy or sweep_size by scenario)"
    parser.add_argument("--out", type=Path, default=Path(default_out) if default_out else None, help=out_help)
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    parser.add_argument("--resume", action="store_true",
                        help="keep the finished seeds of an earlier run with the same settings in --out")
    parser.add_argument("--no-plot", action="store_true", help="skip the PNG figure")
    parser.add_argument("--agent-steps", type=int, default=DEFAULT_AGENT_STEPS,
                        help="steps of the tuned near-optimal agent (PSRL episodic, UCRL2 continuous) per MDP; "
                             "0 leaves the agent out (default %(default)s)")
    parser.add_argument("--agent-candidates", type=int, default=DEFAULT_AGENT_CANDIDATES,
                        help="random-search candidates per MDP; 1: the default hyperparameters (default %(default)s)")
    parser.add_argument("--agent-tuning-seeds", type=int, default=DEFAULT_AGENT_TUNING_SEEDS,
                        help="seeds per candidate in the search (default %(default)s)")
    return parser


# ---------------------------------------------------------------------------------------------------------------
# Results table
# ---------------------------------------------------------------------------------------------------------------


def agent_config(args: argparse.Namespace, spec: scenarios.ScenarioSpec) -> dict[str, Any] | None:
    """The tuned agent's settings, or ``None`` when ``--agent-steps 0``."""
    if args.agent_steps == 0:
        return None
    return dict(
        agent=NEAR_OPTIMAL_AGENTS[spec.setting], steps=args.agent_steps, candidates=args.agent_candidates,
        tuning_seeds=args.agent_tuning_seeds,
    )


def config_of(spec: scenarios.ScenarioSpec, agent: dict[str, Any] | None = None) -> dict[str, Any]:
    """The settings a results table depends on (everything but the seeds), JSON-friendly."""
    return dict(
        scenario=spec.scenario,
        family=spec.family,
        setting=spec.setting,
        parameter=spec.parameter,
        values=list(spec.values),
        params={k: repr(v) for k, v in spec.params},
        variant=spec.variant,
        gamma=spec.gamma,
        agent=agent,
    )


def stem_of(spec: scenarios.ScenarioSpec) -> str:
    suffix = "" if spec.variant == "paper" else f"_{spec.variant}"
    return f"scenario{spec.scenario}_{spec.family}_{spec.setting}{suffix}"


def rows_from_raw(spec: scenarios.ScenarioSpec, seeds: Sequence[int], raw: dict[str, np.ndarray]) -> list[dict]:
    rows = []
    for i, seed in enumerate(seeds):
        for j, value in enumerate(spec.values):
            row = dict(
                scenario=spec.scenario, family=spec.family, setting=spec.setting, variant=spec.variant, seed=int(seed),
                parameter=spec.parameter, value=value, n_states=int(raw["n_states"][i, j]),
            )
            for m in MEASURES:
                row[m] = float(raw[m][i, j])
                row[f"{m}_converged"] = bool(raw[f"{m}_converged"][i, j])
            if "agent" in raw:
                row["agent"] = raw["agent"]
                row["agent_cumulative_regret"] = float(raw["agent_cumulative_regret"][i, j])
                row["agent_normalized_cumulative_regret"] = float(raw["agent_normalized_cumulative_regret"][i, j])
            rows.append(row)
    return rows


def read_rows(path: Path, spec: scenarios.ScenarioSpec) -> list[dict]:
    """Rows of an existing table, parsed back into numbers (the normalised columns are recomputed on write)."""
    cast = int if spec.parameter not in ("p_rand", "p_lazy") else float
    rows = []
    with path.open(newline="") as f:
        for rec in csv.DictReader(f):
            row = dict(
                scenario=int(rec["scenario"]), family=rec["family"], setting=rec["setting"], variant=rec["variant"],
                seed=int(rec["seed"]), parameter=rec["parameter"], value=cast(rec["value"]),
                n_states=int(rec["n_states"]),
            )
            for m in MEASURES:
                row[m] = float(rec[m])
                row[f"{m}_converged"] = rec[f"{m}_converged"] == "True"
            if rec.get("agent"):
                row["agent"] = rec["agent"]
                row["agent_cumulative_regret"] = float(rec["agent_cumulative_regret"])
                row["agent_normalized_cumulative_regret"] = float(rec["agent_normalized_cumulative_regret"])
            rows.append(row)
    return rows


def ordered(spec: scenarios.ScenarioSpec, rows: list[dict]) -> list[dict]:
    """Rows in (seed, value) order of the spec."""
    seed_pos = {s: i for i, s in enumerate(spec.seeds)}
    value_pos = {v: j for j, v in enumerate(spec.values)}
    return sorted(rows, key=lambda r: (seed_pos[r["seed"]], value_pos[r["value"]]))


def curves_of(rows: list[dict], shape: tuple[int, ...] = (1, -1)) -> dict[str, np.ndarray]:
    """App. E min-max normalisation over all rows of every measure and, when the rows have it, of the agent's
    per-step normalised cumulative regret (:data:`AGENT_CURVE`), each reshaped to ``shape``."""
    raw = {m: np.asarray([r[m] for r in rows], np.float64).reshape(shape) for m in MEASURES}
    curves = scenarios.normalize_measures(raw)
    if rows and all("agent" in r for r in rows):
        regret = np.asarray([r["agent_normalized_cumulative_regret"] for r in rows], np.float64).reshape(shape)
        curves[AGENT_CURVE] = scenarios.normalize_padded(regret)
    return curves


def write_table(path: Path, rows: list[dict]) -> None:
    """Write all rows with the normalisation over all of them, atomically (a crash never leaves half a file)."""
    normalized = curves_of(rows)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        for k, row in enumerate(rows):
            out = dict(row)
            for m in MEASURES:
                out[m] = repr(float(row[m]))
                out[f"{m}_normalized"] = repr(float(normalized[m][0, k]))
            if AGENT_CURVE in normalized:
                out["agent_regret_normalized"] = repr(float(normalized[AGENT_CURVE][0, k]))
            out["value"] = repr(row["value"])
            writer.writerow(out)
    os.replace(tmp, path)


def finished_rows(spec: scenarios.ScenarioSpec, rows: list[dict]) -> tuple[list[dict], set[int]]:
    """The rows of the spec's seeds whose whole grid is present, and those seeds."""
    by_seed: dict[int, dict] = {}
    for r in rows:
        if r["seed"] in spec.seeds and r["value"] in spec.values:
            by_seed.setdefault(r["seed"], {})[r["value"]] = r
    done = {s for s, vals in by_seed.items() if len(vals) == len(spec.values)}
    return [r for s in done for r in by_seed[s].values()], done


# ---------------------------------------------------------------------------------------------------------------
# Main
# ---------------------------------------------------------------------------------------------------------------


def run(args: argparse.Namespace, scenario: int, parser: argparse.ArgumentParser) -> dict[str, Path]:
    """Compute the sweep of the parsed ``args`` (module docstring); returns the paths written by kind."""
    seeds = list(args.seed_list) if args.seed_list is not None else list(range(args.seeds))
    if args.out is None:
        args.out = Path(DEFAULT_OUTS[scenario])
    quiet = getattr(args, "quiet", False)
    try:
        spec = scenarios.scenario_spec(
            scenario, args.family, episodic=args.setting == "episodic", seeds=seeds, values=args.values,
            params=dict(args.param), variant=args.variant, gamma=args.gamma,
        )
    except ValueError as err:
        parser.error(str(err))
    if args.seeds_per_call < 1:
        parser.error(f"--seeds-per-call must be >= 1; got {args.seeds_per_call}")
    if args.agent_steps < 0:
        parser.error(f"--agent-steps must be >= 0 (0: no agent); got {args.agent_steps}")
    if args.agent_candidates < 1 or args.agent_tuning_seeds < 1:
        parser.error("--agent-candidates and --agent-tuning-seeds must be >= 1; got "
                     f"{args.agent_candidates} and {args.agent_tuning_seeds}")
    agent = agent_config(args, spec)

    args.out.mkdir(parents=True, exist_ok=True)
    stem = stem_of(spec)
    csv_path, json_path, png_path = (args.out / f"{stem}{ext}" for ext in (".csv", ".json", ".png"))
    config = config_of(spec, agent)

    rows: list[dict] = []
    done: set[int] = set()
    if args.resume and csv_path.exists():
        old = json.loads(json_path.read_text()) if json_path.exists() else None
        if old != config:
            parser.error(
                f"--resume: {csv_path} was made with other settings ({json_path} differs or is missing); "
                "use another --out or run without --resume"
            )
        rows, done = finished_rows(spec, read_rows(csv_path, spec))
    json_path.write_text(json.dumps(config, indent=1) + "\n")

    todo = [s for s in spec.seeds if s not in done]
    if done and not quiet:
        print(f"resuming: {len(done)} of {len(spec.seeds)} seeds already finished", file=sys.stderr)
    if todo:
        t0 = time.perf_counter()
        grid = scenarios.prepare(spec, todo)
        if not quiet:
            print(f"built {grid.batch.T.shape[0]} MDPs ({grid.n_states.min()}-{grid.n_states.max()} states) in "
                  f"{time.perf_counter() - t0:.1f} s", file=sys.stderr)
        label = f"scenario {spec.scenario} {spec.family} {spec.setting}"
        with Progress(len(todo), label, "seeds", quiet=quiet, unit_scale=False) as bar:
            k = args.seeds_per_call
            for start in range(0, len(todo), k):
                chunk = todo[start : start + k]
                # A short last chunk is filled up with copies of its first seed so that it reuses the compiled program.
                chunk_grid = grid.take(chunk + [chunk[0]] * (k - len(chunk)))
                raw = scenarios.compute(chunk_grid)
                if agent is not None:
                    raw.update(agent_regret(chunk_grid, agent))
                raw = {name: a if name == "agent" else a[: len(chunk)] for name, a in raw.items()}
                rows += rows_from_raw(spec, chunk, raw)
                write_table(csv_path, ordered(spec, rows))
                bar.update(len(chunk))
    else:
        write_table(csv_path, ordered(spec, rows))

    written = {"csv": csv_path, "json": json_path}
    if not args.no_plot:
        written["png"] = figure(spec, ordered(spec, rows), png_path)
    for path in written.values():
        print(path)
    return written


def agent_regret(grid: scenarios.ScenarioGrid, agent: dict[str, Any]) -> dict[str, Any]:
    """The tuned near-optimal agent's regret on every MDP of ``grid``
    (:func:`hardness.analysis.near_optimal.tuned_regret`); MDP ``(seed, value)`` is evaluated with that seed. Arrays
    ``[n_seeds, n_values]``."""
    n, V = len(grid.seeds), len(grid.spec.values)
    result = tuned_regret(
        scenarios.grid_mdps(grid), np.repeat(grid.seeds, V), n_steps=agent["steps"],
        n_candidates=agent["candidates"], n_tuning_seeds=agent["tuning_seeds"],
    )
    return {
        "agent": result.agent,
        "agent_cumulative_regret": result.cumulative_regret.reshape(n, V),
        "agent_normalized_cumulative_regret": result.normalized_cumulative_regret.reshape(n, V),
    }


def figure(spec: scenarios.ScenarioSpec, rows: list[dict], path: Path) -> Path:
    """The scenario's figure from its table rows (normalised over all rows, as in the table)."""
    n, V = len(spec.seeds), len(spec.values)
    curves = curves_of(rows, (n, V))
    if spec.scenario in (3, 4):
        x = np.asarray([r["n_states"] for r in rows], np.float64).reshape(n, V).mean(axis=0)
        xlabel = "n_states"
    else:
        x, xlabel = np.asarray(spec.values, np.float64), spec.parameter
    fixed = ", ".join(f"{k}={v}" for k, v in spec.params if v is not None)
    title = f"Scenario {spec.scenario}: {spec.family} {spec.setting} ({spec.variant}), {n} seeds\n{fixed}"
    agents_seen = sorted({r["agent"] for r in rows if "agent" in r})
    if agents_seen:
        title += f"; tuned agent: {', '.join(agents_seen)}"
    return plot_scenario(x, curves, path, xlabel=xlabel, title=title)


def main(scenario: int, argv: Sequence[str] | None = None, *, description: str = "", default_out: str | None = None,
         scenario_choices: Sequence[int] | None = None, entry_point: bool = False) -> int:
    """Run one sweep from its command line; ``scenario_choices`` adds ``--scenario`` (default: the first choice).

    ``entry_point=True`` (the console commands, not in-process callers such as the tests) turns on the persistent
    compilation cache (``--no-compile-cache`` turns it off; :mod:`jaxmdp.experiment.compilation`) and reports the time
    spent compiling beside the total time on stderr.
    """
    choices = list(scenario_choices or [scenario])
    parser = build_parser(description, default_out, choices)
    if entry_point:
        compilation.add_cache_flag(parser)
    args = parser.parse_args(argv)
    if entry_point:
        folder, stats = compilation.setup_compilation(args.no_compile_cache)
        t0 = time.perf_counter()
    run(args, getattr(args, "scenario", scenario), parser)
    if entry_point:
        print(compilation.time_report(time.perf_counter() - t0, stats.snapshot(), folder), file=sys.stderr)
    return 0
