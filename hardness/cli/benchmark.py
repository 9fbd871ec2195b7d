"""``jaxmdp-benchmark``: the Colosseum benchmark (paper §3.3, App. F, App. G), in three subcommands.

* ``run``: every (MDP, agent, seed) of the chosen sets runs all its steps (no wall-clock cut-off) in lockstep batches
  grouped by size; results are written as each batch finishes, and running again on the same folder continues where
  it stopped (finished batches are never redone; the final ``members.csv`` is the same byte for byte). See
  :mod:`hardness.benchmark.run` for the output folder and :mod:`hardness.benchmark.report` for the report.
* ``report``: the report (tables as Markdown and LaTeX, cumulative-regret and hardness figures) of a ``run`` output
  folder, from the batches finished so far; ``report DIR1 DIR2 ... --out DIR`` first merges run folders of one
  protocol (e.g. the shards of a run, ``run --shard i/N``) into ``DIR`` (:mod:`hardness.benchmark.shards`).
* ``tune``: the random search of the tabular agents' hyperparameters (:mod:`hardness.benchmark.search`), whose
  winners, with their provenance, go to ``tuned_hparams.json`` in the output folder (a copy of the shipped file,
  ``hardness/benchmark/tuned_hparams.json``, with the new entries), which ``run --hparams PATH`` reads.

Your own agent (docs/guide/own_agent.md): ``--agents module:NAME`` (or ``path/to/file.py:NAME``) imports the module
(the current directory first on the path, as ``python -m``) and registers its :class:`~jaxmdp.agent_interface.Agent`
``NAME`` (:func:`agents.register`); ``--baseline committed`` sets the shipped agents' committed results beside it in
the report, without running them, when they were made under the same protocol (else it stops and names what
differs); ``--baseline DIR`` does so with another run folder.

    jaxmdp-benchmark run --quick --out results/benchmark_quick       # the quick-test sets, a few minutes
    jaxmdp-benchmark run --settings episodic_ergodic --seeds 20 --steps 500000 --out results/benchmark
    jaxmdp-benchmark run --settings continuous_ergodic --agents ucrl2 --hparams reference --out DIR
    jaxmdp-benchmark run --quick --hparams reference --agent-variant colosseum --out DIR   # reference mode
    jaxmdp-benchmark run --quick --hparams reference --agent-variant colosseum --indicators colosseum --out DIR
    jaxmdp-benchmark run --quick --emission StateInfo --agents dqn_episodic random_episodic --out DIR
    jaxmdp-benchmark run --quick --agents my_agents:MY_AGENT --baseline committed --out DIR   # your agent
    jaxmdp-benchmark report results/benchmark_quick
    jaxmdp-benchmark run --quick --shard 0/2 --out DIR0; jaxmdp-benchmark run --quick --shard 1/2 --out DIR1
    jaxmdp-benchmark report DIR0 DIR1 --out DIR                            # the shards merged, the single run's
    jaxmdp-benchmark run --emission state_info --agents boot_dqn_episodic --part-members 8 --out DIR   # in pieces
    jaxmdp-benchmark run --quick --ray --out DIR                            # batches as tasks of a local Ray
    jaxmdp-benchmark run --settings episodic_ergodic --ray auto --gpus-per-batch 0.25 --out DIR   # a Ray cluster
    jaxmdp-benchmark report DIR --baseline committed
    jaxmdp-benchmark tune --out results/tuning                            # every tabular agent, full budget
    jaxmdp-benchmark tune --agents ucrl2 --steps 20000 --candidates 8 --mdps-per-family 1 --seeds 1
    jaxmdp-benchmark tune --ray --out results/tuning                      # each agent's search a Ray task
    jaxmdp-benchmark tune --agents my_agents:MY_AGENT --out DIR; jaxmdp-benchmark run --hparams DIR/tuned_hparams.json ...

``run`` and ``tune`` shard the members over one host device per core (set here, before JAX starts its backend, unless
``XLA_FLAGS`` already sets the device count).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from hardness.cli._common import add_cache_flag, compile_report, load_agents
from jaxmdp.experiment.progress import LOG_EVERY_S

if TYPE_CHECKING:  # imported on use: hardness.benchmark starts JAX's backend, after main() set the host devices
    from hardness.benchmark.run import RunConfig, RunSummary
    from hardness.benchmark.search import Budget

__all__ = ["build_parser", "config_from_args", "ray_from_args", "main", "report_command", "run_command",
           "tune_command"]

_RAW = argparse.RawDescriptionHelpFormatter

TUNE_HELP = """Tune the tabular agents by random search (paper App. F) and write the winners, with their provenance, to
the tuned file the benchmark reads.

Defaults are the reference's code-default budget (50 candidates drawn with seeds 42, 43, ..., 5 MDPs per family from
every family's sampler with seed 42, seeds 0-2, 250 000 steps), plus the reference's cached values as one more
candidate. Pass smaller numbers for a reduced run (the file records the budget and marks it reduced).

The winners go to ``tuned_hparams.json`` in ``--out`` (a folder, default ``results/tuning``; a path ending in
``.json`` names the file itself, e.g. the shipped ``hardness/benchmark/tuned_hparams.json`` when regenerating it from a
checkout); a new file starts as a copy of the shipped one, so that it is a complete tuned file for ``run --hparams
PATH``. Nothing is written inside the installed package unless its path is given.

The file is rewritten after every agent, and every size bucket of a search keeps a CSV and a checkpoint in
``--work-dir`` (default ``runs/`` beside the tuned file, a folder per agent and budget), so a killed run started again
with the same arguments resumes: agents whose entry in the file already has this budget are skipped (``--redo``
reruns them) and an unfinished search continues from its last checkpoint. Each entry records the search's wall time
(``wall_s``, building the MDPs, compiling and running).

Your own agent: ``--agents module:NAME`` (registered with a search space, ``agents.register(agent, search_space)``,
by its module).
"""


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``run``."""
    from hardness.benchmark import run, sets

    p.add_argument("--settings", nargs="+", default=None, metavar="SET",
                   help=f"benchmark sets (default: the four settings); one of: {', '.join(sets.SET_NAMES)}")
    p.add_argument("--agents", nargs="+", default=None,
                   help="agents by registry name, or your own as module:NAME or path/to/file.py:NAME (an Agent, "
                        "registered on import; the current directory is on the path) (default: every tabular agent of "
                        "each set's type; --quick: all but psrl_continuous; with --emission: every deep agent of the "
                        "set's type and the random agent)")
    p.add_argument("--mdps", nargs="+", default=None, metavar="MDP",
                   help="keep only these MDPs of the sets: labels (RiverSwim/prms_0) or families (default: all)")
    p.add_argument("--seeds", type=int, default=None, help="number of seeds 0..N-1 (default 20; --quick 2)")
    p.add_argument("--steps", type=int, default=None, help="steps per run (default 500000; --quick "
                   f"{run.QUICK['n_steps']})")
    p.add_argument("--log-period", type=int, default=None,
                   help="steps between indicator logs (default 100; --quick: 1000 episodic, 500 continuous)")
    p.add_argument("--hparams", default="tuned",
                   help="tuned (the shipped hardness/benchmark/tuned_hparams.json), reference (the reference's cached "
                        "values) or a tuned-file path, e.g. one written by tune (default %(default)s)")
    p.add_argument("--agent-variant", default="paper", choices=("paper", "colosseum"),
                   help="paper: the agents follow their algorithms' papers (default); colosseum: reference mode, the "
                        "tabular agents with the reference package's update rules (docs/agents.md); with --hparams "
                        "reference the like-for-like counterpart of the paper's Table 2")
    p.add_argument("--indicators", default="paper", choices=("paper", "colosseum"),
                   help="paper: the exact expected regret as the paper defines it (default); colosseum: the "
                        "reference's indicators (episodic regret at the last episode's start, rho* of the "
                        "0.99-discounted greedy policy, regrets <= 1e-3 zeroed; docs/measures.md)")
    p.add_argument("--stop-when-converged", action="store_true",
                   help="the reference's convergence stop: a run whose normalised regret stayed near 0 for ten logs "
                        "past a fifth of its steps stops learning (docs/measures.md; off: learn to the end)")
    p.add_argument("--buckets", type=int, default=None,
                   help="size buckets per set for every agent (default 4, 8 for episodic PSRL, whose posterior "
                        "draws pay for the padding at every episode, and 2 for the deep agents, one program each; "
                        "--quick 1)")
    p.add_argument("--max-members", type=int, default=None,
                   help="members per runner call (default: a bucket, halved until it fits in memory)")
    p.add_argument("--memory-limit", type=float, default=None, metavar="GIB",
                   help="GiB a runner call may use (default: the memory available)")
    p.add_argument("--part-members", type=int, default=None, metavar="N",
                   help="run each batch of more than N members in parts of at most N, each written when it finishes, "
                        "with the same results: hours-long batches in pieces that a machine finishes before it goes "
                        "(default: whole batches; not with --ray)")
    p.add_argument("--emission", default=None,
                   help="observe the MDPs through this emission map, for the deep agents: state_info (the reference's "
                        "StateInfo), one_hot (OneHotEncoding), image, tensor, linear_optimal, linear_random (default: "
                        "the states, tabular agents); with it the default agents are the deep agents and the random "
                        "agent")
    p.add_argument("--quick", action="store_true", help="the quick-test sets, 2 seeds, few steps")
    p.add_argument("--shard", type=_shard, default=None, metavar="i/N",
                   help="run only shard i of N (counted from 0) of the batches, a deterministic share, e.g. one job "
                        "of an array each (--shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT); merge the shards' "
                        "folders with: report DIR1 DIR2 ... --out DIR (default: every batch)")
    add_ray_arguments(p, "batches", "the driver writes every table (default: one batch after another in this "
                      "process)")
    add_baseline_argument(p)
    p.add_argument("--out", type=Path, required=True,
                   help="output folder (reused to resume; several processes may share it, each batch runs once)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--log-every", type=_log_every, default=LOG_EVERY_S, metavar="SECONDS",
                   help="when stderr is not a terminal (a log file), a progress line at most every SECONDS: done, "
                        "elapsed, left, rate (default %(default)g; 0: none)")
    add_cache_flag(p)
    p.set_defaults(func=run_command)


def _shard(text: str) -> tuple[int, int]:
    """``--shard``'s value (:func:`hardness.benchmark.shards.parse_shard`), its error shown by argparse."""
    from hardness.benchmark import shards

    try:
        return shards.parse_shard(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err).removeprefix("--shard ")) from None


def _log_every(text: str) -> float | None:
    """``--log-every``'s value: seconds > 0, or 0 for no progress lines (``None``)."""
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a number of seconds >= 0; got {text!r}")
    return value or None


def _fraction(text: str) -> float:
    """A number >= 0 (``--gpus-per-batch``, ``--cpus-per-batch``)."""
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a number >= 0; got {text!r}")
    return value


def ray_from_args(args: argparse.Namespace) -> object:
    """``run_benchmark``'s ``ray`` of ``--ray``, ``--gpus-per-batch`` and ``--cpus-per-batch`` (``None`` without
    ``--ray``; Ray itself is imported only when the batches are handed out)."""
    if args.ray is None:
        if args.gpus_per_batch is not None or args.cpus_per_batch != 1:
            raise ValueError("--gpus-per-batch and --cpus-per-batch are for --ray runs")
        return None
    from hardness.benchmark.distributed import RayOptions, ray_options

    address = None if args.ray is True else args.ray
    return ray_options(RayOptions(address=address, cpus_per_batch=args.cpus_per_batch,
                                  gpus_per_batch=args.gpus_per_batch))


def add_baseline_argument(p: argparse.ArgumentParser) -> None:
    """``--baseline``, of ``run`` and ``report``."""
    p.add_argument("--baseline", default=None, metavar="committed|DIR",
                   help="set other results beside this run's in the report, without running them: committed (the "
                        "shipped agents' committed results, package data) or a run folder; refused, naming what "
                        "differs, unless they were made under this run's protocol (steps, seeds, log period, "
                        "emission, agent rules, indicators, hyperparameter source)")


def add_report_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``report``."""
    p.add_argument("folder", type=Path, nargs="*", default=[],
                   help="the run's output folder (or --out); several: folders of one protocol (e.g. the shards of a "
                        "run) merged into --out")
    add_baseline_argument(p)
    p.add_argument("--out", type=Path, default=None,
                   help="the run's output folder, where the report goes; with folders named: the folder they are "
                        "merged into (it may be one of them)")
    p.add_argument("--quiet", action="store_true", help="do not list the files written on stdout")
    add_cache_flag(p)
    p.set_defaults(func=report_command)


def add_ray_arguments(p: argparse.ArgumentParser, what: str, default: str) -> None:
    """``--ray [ADDRESS]``, ``--gpus-per-batch`` and ``--cpus-per-batch`` of ``run`` (its batches) and ``tune`` (its
    agents' searches)."""
    p.add_argument("--ray", nargs="?", const=True, default=None, metavar="ADDRESS",
                   help=f"run the {what} as Ray tasks (needs the [distributed] extra): alone, on a local Ray instance "
                        "of this machine's cores and GPUs; with an address, on that cluster (auto: the cluster this "
                        f"machine joined with ray start); {default}")
    p.add_argument("--gpus-per-batch", type=_fraction, default=None, metavar="F",
                   help=f"with --ray: GPUs each of the {what} declares; a fraction packs several on one GPU, e.g. "
                        "0.25 runs four at once (default: 1 where the cluster has GPUs, else 0)")
    p.add_argument("--cpus-per-batch", type=_fraction, default=1, metavar="N",
                   help=f"with --ray: CPU cores each of the {what} declares, and the host devices its members are "
                        "sharded over (default %(default)s)")


def add_tune_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``tune``."""
    from agents.search_spaces import SEARCH_SPACES
    from hardness.benchmark import hparams, search

    import agents

    default = search.Budget()
    shipped = [n for n in SEARCH_SPACES if n in agents.SHIPPED]
    p.add_argument("--agents", nargs="+", default=shipped,
                   help=f"agents with a search space: {', '.join(shipped)}, or your own as module:NAME (default: "
                        "every shipped one)")
    p.add_argument("--steps", type=int, default=default.n_steps, help="steps per run (%(default)s)")
    p.add_argument("--candidates", type=int, default=default.n_candidates, help="sampled candidates (%(default)s)")
    p.add_argument("--mdps-per-family", type=int, default=default.n_per_family, help="%(default)s")
    p.add_argument("--seeds", type=int, default=default.n_seeds, help="number of seeds 0..N-1 (%(default)s)")
    p.add_argument("--log-period", type=int, default=default.log_period, help="%(default)s")
    p.add_argument("--max-states", type=int, default=None, help="leave out sampled MDPs with more states")
    p.add_argument("--no-reference-candidate", action="store_true",
                   help="do not add the reference's cached values as a candidate")
    p.add_argument("--buckets", type=int, default=4, help="size buckets per search (%(default)s)")
    p.add_argument("--note", default="", help="a note stored with each entry")
    p.add_argument("--out", type=Path, default=Path("results/tuning"),
                   help="output folder, the winners in its tuned_hparams.json (a path ending in .json: that file; "
                        f"the shipped one is {hparams.TUNED_FILE}) (default %(default)s)")
    p.add_argument("--work-dir", type=Path, default=None,
                   help="runner CSVs and checkpoints, one folder per agent, to resume from (default: runs/ beside "
                        "the tuned file)")
    p.add_argument("--redo", action="store_true", help="rerun agents already tuned with this budget in the file")
    add_ray_arguments(p, "agents' searches", "the winners are written as each search ends (default: one agent after "
                      "another in this process)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    add_cache_flag(p)
    p.set_defaults(func=tune_command)


def build_parser() -> argparse.ArgumentParser:
    """``jaxmdp-benchmark {run,report,tune} ...``."""
    p = argparse.ArgumentParser(prog="jaxmdp-benchmark", description=__doc__, formatter_class=_RAW)
    sub = p.add_subparsers(dest="command", required=True, metavar="{run,report,tune}")
    add_run_arguments(sub.add_parser("run", help="run the benchmark to completion (resumable)",
                                     description=__doc__, formatter_class=_RAW))
    add_report_arguments(sub.add_parser("report", help="write the report of a run's folder",
                                        description=__doc__, formatter_class=_RAW))
    add_tune_arguments(sub.add_parser("tune", help="tune the tabular agents by random search",
                                      description=TUNE_HELP, formatter_class=_RAW))
    return p


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """The run's :class:`hardness.benchmark.run.RunConfig`: ``--quick`` defaults (or the benchmark's), overridden by
    the options given."""
    from hardness.benchmark import run, sets

    base = dict(run.QUICK) if args.quick else dict(sets=sets.SETTINGS)
    if args.emission is not None:
        base.pop("agents", None)  # --quick's agents are tabular; with an emission: the deep agents and random
    given = dict(sets=tuple(args.settings) if args.settings else None,
                 agents=tuple(load_agents(args.agents)) if args.agents else None,
                 seeds=tuple(range(args.seeds)) if args.seeds is not None else None, n_steps=args.steps,
                 n_buckets=args.buckets, max_members=args.max_members, emission=args.emission,
                 only=tuple(args.mdps) if args.mdps else None,
                 memory_limit=None if args.memory_limit is None else int(args.memory_limit * 2**30),
                 part_members=args.part_members)
    config = {**base, **{k: v for k, v in given.items() if v is not None}, "hparams": args.hparams,
              "agent_variant": args.agent_variant, "indicator_variant": args.indicators,
              "stop_when_converged": args.stop_when_converged}
    if args.buckets is not None:
        config.update(agent_buckets={})  # --buckets N: N for every agent
    if args.log_period is not None:
        config.update(log_period=args.log_period, log_periods={})
    return run.RunConfig(**config)


def run_command(args: argparse.Namespace) -> RunSummary:
    """``run``: the benchmark of the parsed ``args``; returns its :class:`hardness.benchmark.run.RunSummary`."""
    from hardness.benchmark import run

    try:
        config = config_from_args(args)
        return run.run_benchmark(config, args.out, progress=not args.quiet, log_every=args.log_every,
                                 baseline=args.baseline, shard=args.shard, ray=ray_from_args(args))
    except (ValueError, ImportError) as err:
        raise SystemExit(f"jaxmdp-benchmark run: {err}") from None


def report_command(args: argparse.Namespace) -> list[Path]:
    """``report``: the report of the run folder ``args.folder`` (or ``args.out``); returns the paths written."""
    from hardness.benchmark import report, shards

    folders = list(args.folder)
    if not folders and args.out is None:
        raise SystemExit("jaxmdp-benchmark report: name the run's folder (positional or --out)")
    if len(folders) > 1 and args.out is None:
        raise SystemExit("jaxmdp-benchmark report: several folders are merged: name the merged folder with --out")
    folder = args.out if args.out is not None else folders[0]
    for f in folders or [folder]:
        if not (f / "plan.json").exists() or not (f / "members.csv").exists():
            raise SystemExit(f"jaxmdp-benchmark report: {f} holds no benchmark run (plan.json and members.csv)")
    try:
        if folders and [f.resolve() for f in folders] != [folder.resolve()]:
            shards.merge_folders(folders, folder)
        written = report.write_report(folder, args.baseline)
    except ValueError as err:
        raise SystemExit(f"jaxmdp-benchmark report: {err}") from None
    if not args.quiet:
        print("\n".join(map(str, written)))
    return written


def tune_command(args: argparse.Namespace) -> dict:
    """``tune``: search every agent of ``args.agents`` not yet tuned with this budget; returns the new entries."""
    from hardness.benchmark import search

    try:
        names = load_agents(args.agents)
        for name in names:
            search.check_tunable(name)
        ray = ray_from_args(args)
    except ValueError as err:
        raise SystemExit(f"jaxmdp-benchmark tune: {err}") from None
    path, work_dir = tuned_paths(args.out, args.work_dir)
    budget = search.Budget(n_steps=args.steps, n_candidates=args.candidates, n_per_family=args.mdps_per_family,
                           n_seeds=args.seeds, log_period=args.log_period, max_states=args.max_states,
                           include_reference=not args.no_reference_candidate)
    if not path.exists():
        search.start_tuned_file(path)
    done = json.loads(path.read_text()).get("agents", {}) if not args.redo else {}
    todo = []
    for name in names:
        if name in done and _same_budget(done[name], budget):
            print(f"{name}: already tuned with this budget in {path}; skipped (--redo reruns it)",
                  file=sys.stderr, flush=True)
        else:
            todo.append(name)
    if ray is not None and todo:  # one Ray task per agent's search
        from hardness.benchmark import distributed_tune

        def write(name: str, entry: dict) -> None:
            search.write_tuned(path, {name: entry})
            _print_winner(name, entry)

        try:
            return distributed_tune.tune_agents(todo, budget, {n: work_dir / n / _slug(budget) for n in todo}, ray,
                                                n_buckets=args.buckets, note=args.note, on_entry=write)
        except ValueError as err:
            raise SystemExit(f"jaxmdp-benchmark tune: {err}") from None
    entries = {}
    for name in todo:
        if not args.quiet:
            print(f"tuning {name}: {budget}", file=sys.stderr, flush=True)
        try:
            entries[name] = search.tuned_entry(name, budget, n_buckets=args.buckets, work_dir=work_dir / name /
                                               _slug(budget), note=args.note, progress=not args.quiet)
        except ValueError as err:
            raise SystemExit(f"jaxmdp-benchmark tune: {err}") from None
        search.write_tuned(path, {name: entries[name]})  # after every agent, so an interruption keeps it
        _print_winner(name, entries[name])
    return entries


def _print_winner(name: str, e: dict) -> None:
    print(f"  {name}: winner {e['winner']} {e['values']}, objective per step {e['objective_per_step']:.4f} "
          f"(run {e['run_s']} s, compile {e['compile_s']} s, wall {e['wall_s']} s)", file=sys.stderr, flush=True)


def tuned_paths(out: Path, work_dir: Path | None) -> tuple[Path, Path]:
    """``(tuned file, work folder)`` of ``tune --out OUT [--work-dir W]``: ``OUT/tuned_hparams.json`` and
    ``OUT/runs``, or, for an ``OUT`` ending in ``.json``, that file and ``runs/`` beside it."""
    path = out if out.suffix == ".json" else out / "tuned_hparams.json"
    return path, work_dir if work_dir is not None else path.parent / "runs"


def _slug(budget: Budget) -> str:
    """A folder name for one budget, so checkpoints of different budgets never meet."""
    return "-".join(f"{k}{v}" for k, v in dataclasses.asdict(budget).items()).replace("_", "")


def _same_budget(entry: dict, budget: Budget) -> bool:
    """Whether a tuned-file entry was searched with ``budget`` (every field of ``hardness.benchmark.search.Budget``)."""
    return all(entry.get("budget", {}).get(k) == v for k, v in dataclasses.asdict(budget).items())


def main(argv: Sequence[str] | None = None) -> int:
    """``jaxmdp-benchmark {run,report,tune} ...`` (module docstring)."""
    from jaxmdp.experiment.devices import use_every_core

    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] in (["run"], ["tune"]):
        # One lockstep loop per core: the runner shards the members over the host devices (set before JAX starts).
        use_every_core()
    args = build_parser().parse_args(argv)
    with compile_report(args.no_compile_cache):
        args.func(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
