"""Measure a fraction of the full tabular benchmark and extrapolate its wall time (paper §3.3; issue "Performance").

The full run is :func:`hardness.benchmark.run.plan` of the four settings, every tabular agent, 20 seeds, 500 000 steps
and indicators every 100 steps: one batch per (setting, agent, size bucket). This script runs, for every agent of each
measured setting, the smallest and the largest size bucket of that plan (``--which largest``: the largest only), with
fewer seeds and steps, through the benchmark's own batches (one ``run_benchmark`` call per bucket, ``n_buckets=1`` on
exactly that bucket's MDPs), and records each batch's compile and run seconds (its ``batches.csv``) and the process CPU
seconds it used.

Extrapolation, for every batch of the full plan: run seconds = fixed seconds + (measured run seconds per member-step,
interpolated linearly in the bucket's largest state count between the measured buckets of the same agent and setting
type, clipped at them; one measured bucket: its rate) x members x steps; compile seconds = the mean of the measured
compiles (compiling does not depend on the member count or the steps). An unmeasured setting uses the measured one of
its type (episodic, continuous).

* One step count (``--steps N``): the rate is run seconds / (members x N), which also charges the call's fixed cost
  (the first execution of a program, the first logs) to the steps; the fixed seconds are 0.
* Two step counts (``--steps N1 N2``): each bucket runs both, in this process (the second run reuses the first's
  compiled program). The rate is the difference of the two runs' seconds / (members x (N2 - N1)), the fixed seconds
  the rest of the first run. Where the second run was not slower (noise), the longer run's single-point rate is used.
  Both runs must be cut into as many runner chunks as the full run (20, :func:`~jaxmdp.experiment.runner.
  default_chunk_steps`; ``N1 >= 2000``): each chunk ends with a checkpoint of the batch's state (0.3-0.5 s for 20
  members of PSRL at 948 states), which a difference of runs with unequal chunk counts would charge to the steps.
* ``--scaling lockstep-step`` (for a GPU, where a batch's step is bound by latency rather than by its members): the
  cost of a lockstep step, rate x the measured batch's members, is interpolated in states instead, and a full batch
  pays it for every step whatever its member count.

The measured runs and ``wall_time.json`` go to ``--work-dir`` (a second call on the same folder reuses the measured
buckets); the table of the extrapolation per setting and agent to ``results/benchmarks/benchmark_wall_time.md``
(``--update-docs``: also docs/performance.md).

    python benchmarks/benchmark_wall_time.py
    python benchmarks/benchmark_wall_time.py --which largest --seeds 2 --steps 500
    python benchmarks/benchmark_wall_time.py --work-dir results/wall_gpu --which largest --seeds 20 --steps 500 5000 \
        --scaling lockstep-step
    python benchmarks/benchmark_wall_time.py --smoke
"""

from __future__ import annotations

import os

if __name__ == "__main__" and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    # One lockstep loop per core, as jaxmdp-benchmark run runs (set before JAX starts).
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={os.cpu_count() or 1}"
    ).strip()

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from hardness.benchmark import run, sets  # noqa: E402
from jaxmdp.experiment import compilation, runner  # noqa: E402

import _common  # noqa: E402

NAME = "benchmark_wall_time"

FULL = dict(seeds=tuple(range(20)), n_steps=500_000, log_period=100, n_buckets=4)
SCALINGS = ("member-step", "lockstep-step")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--measure", nargs="+", default=["episodic ergodic", "continuous ergodic"], metavar="SET",
                   help="settings to measure (default: the two ergodic ones)")
    p.add_argument("--agents", nargs="+", default=None, help="agents to measure (default: each setting's tabular)")
    p.add_argument("--seeds", type=int, default=2, help="seeds per measured batch (%(default)s)")
    p.add_argument("--steps", type=int, nargs="+", default=[1000], metavar="N",
                   help="steps per measured batch (%(default)s); two counts N1 < N2 separate the fixed cost of a call "
                        "from the cost per step")
    p.add_argument("--scaling", choices=SCALINGS, default="member-step",
                   help="how a measured cost carries to a batch of other members: per member-step (default; a CPU), "
                        "or per lockstep step whatever the members (a GPU bound by latency)")
    p.add_argument("--which", choices=["ends", "largest", "smallest"], default="ends",
                   help="buckets measured per agent: the smallest and the largest (default), or only the largest, "
                        "whose cost per member-step then stands for every bucket (an upper bound: the cost grows "
                        "with the states), or only the smallest (a lower bound)")
    p.add_argument("--work-dir", type=Path, default=Path("results/benchmark_wall_time"),
                   help="folder for the measured runs and wall_time.json (%(default)s)")
    _common.add_common_args(p)
    return p


def _cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def n_chunks(n_steps: int) -> int:
    """Runner chunks of a benchmark batch of ``n_steps`` steps (the run's default chunking and record period)."""
    period, _ = runner.record_steps(n_steps, FULL["log_period"], run.RunConfig.n_records)
    return -(-n_steps // runner.default_chunk_steps(n_steps, period))


def measure(set_name: str, agent: str, labels: list[str], seeds: int, steps: int, out: Path) -> dict:
    """Run ``agent`` on the MDPs ``labels`` of ``set_name`` as one batch; its timings and the CPU seconds used."""
    config = run.RunConfig(sets=(set_name,), agents=(agent,), seeds=tuple(range(seeds)), n_steps=steps,
                           log_period=FULL["log_period"], hparams="reference", n_buckets=1, agent_buckets={},
                           only=tuple(labels))
    cpu, wall = _cpu_s(), time.perf_counter()
    run.run_benchmark(config, out, progress=False, report=False)
    cpu, wall = _cpu_s() - cpu, time.perf_counter() - wall
    with open(out / "batches.csv") as f:
        (row,) = list(csv.DictReader(f))
    return dict(set=set_name, agent=agent, members=int(row["members"]), max_states=int(row["max_states"]),
                steps=steps, compile_s=float(row["compile_s"]), run_s=float(row["run_s"]), wall_s=wall, cpu_s=cpu)


def rate_and_fixed(m: dict) -> tuple[float, float]:
    """Run seconds per member-step and fixed seconds per call of a measured batch ``m`` (module docstring)."""
    if "steps2" in m and m["run2_s"] > m["run_s"]:
        rate = (m["run2_s"] - m["run_s"]) / (m["members"] * (m["steps2"] - m["steps"]))
        return rate, m["run_s"] - rate * m["members"] * m["steps"]
    if "steps2" in m:  # the longer run was not slower: no difference to take, charge everything to its steps
        return m["run2_s"] / (m["members"] * m["steps2"]), 0.0
    return m["run_s"] / (m["members"] * m["steps"]), 0.0


def extrapolate(full_batches: list[dict], measured: list[dict], scaling: str = "member-step") -> list[dict]:
    """Each full batch (``set, agent, members, max_states``) with its estimated ``run_s`` and ``compile_s`` (``None``
    when no batch of its agent on a setting of its type was measured); ``scaling`` as in the module docstring."""
    if scaling not in SCALINGS:
        raise ValueError(f"scaling must be one of {SCALINGS}, got {scaling!r}")
    rows = []
    for b in full_batches:
        same = [m for m in measured if m["agent"] == b["agent"] and m["set"] == b["set"]]
        if not same:
            same = [m for m in measured if m["agent"] == b["agent"]
                    and sets.is_episodic(m["set"]) == sets.is_episodic(b["set"])]
        if not same:
            rows.append({**b, "run_s": None, "compile_s": None})
            continue
        same.sort(key=lambda m: m["max_states"])
        rates, fixed = zip(*(rate_and_fixed(m) for m in same))
        states = [m["max_states"] for m in same]
        if scaling == "member-step":
            per_step = np.interp(b["max_states"], states, rates) * b["members"]
        else:
            per_step = np.interp(b["max_states"], states, [r * m["members"] for r, m in zip(rates, same)])
        run_s = np.interp(b["max_states"], states, fixed) + per_step * FULL["n_steps"]
        rows.append({**b, "run_s": float(run_s), "compile_s": float(np.mean([m["compile_s"] for m in same]))})
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.smoke:  # the smallest bucket of the random agent on the small quick-test set, one seed, few steps
        args.measure, args.agents, args.seeds, args.steps, args.which = ["episodic quick test"], \
            ["random_episodic"], 1, [100], "smallest"
    if len(args.steps) > 2 or min(args.steps) < 1 or args.steps != sorted(set(args.steps)):
        parser.error(f"--steps takes one count or two increasing counts N1 < N2 (each >= 1), got {args.steps}")
    chunks = [n_chunks(n) for n in args.steps]
    if len(args.steps) == 2 and chunks != [n_chunks(FULL["n_steps"])] * 2:
        parser.error(f"--steps {args.steps[0]} {args.steps[1]} cut the runs into {chunks[0]} and {chunks[1]} runner "
                     f"chunks, the full run into {n_chunks(FULL['n_steps'])}: each chunk ends with a checkpoint, whose "
                     "cost the difference would charge to the steps; take N1 >= 2000")
    # A second call with other steps loads the first's programs (the batches' compile_s then counts loading them).
    cache_folder, compile_stats = compilation.setup_compilation(args.no_compile_cache)
    t_script = time.perf_counter()
    work = args.work_dir
    work.mkdir(parents=True, exist_ok=True)
    settings = tuple(args.measure) if args.smoke else sets.SETTINGS  # smoke: only the measured setting's plan
    full = run.RunConfig(sets=settings, hparams="reference", seeds=FULL["seeds"], n_steps=FULL["n_steps"],
                         log_period=FULL["log_period"], n_buckets=FULL["n_buckets"])
    _, batches = run.plan(full)
    sizes = {}
    for s in settings:
        for inst in sets.instances(s):
            sizes[(s, inst.label)] = inst.build(0).n_states
    full_batches = [dict(set=b.set_name, agent=b.agent, bucket=b.id.split(".")[-1], members=len(b.members),
                         max_states=max(sizes[(b.set_name, m)] for m, _ in b.members)) for b in batches]
    state_path = work / "measured.json"
    measured = json.loads(state_path.read_text()) if state_path.exists() else []
    for set_name in args.measure:
        for agent in args.agents or run.default_agents(set_name):
            if agent not in run.default_agents(set_name):
                continue
            ours = [b for b in batches if b.set_name == set_name and b.agent == agent]
            for b in {"ends": (ours[0], ours[-1]), "largest": (ours[-1],), "smallest": (ours[0],)}[args.which]:
                if any(m["set"] == set_name and m["agent"] == agent and m["bucket"] == b.id for m in measured):
                    continue
                labels = sorted({m for m, _ in b.members})
                if len(args.steps) == 1:
                    m = measure(set_name, agent, labels, args.seeds, args.steps[0], work / b.id)
                else:
                    m, m2 = (measure(set_name, agent, labels, args.seeds, n, work / b.id / f"steps_{n}")
                             for n in args.steps)
                    m.update(steps2=m2["steps"], run2_s=m2["run_s"], compile2_s=m2["compile_s"], wall_s=m["wall_s"]
                             + m2["wall_s"], cpu_s=m["cpu_s"] + m2["cpu_s"])
                measured.append({**m, "bucket": b.id, "full_members": len(b.members)})
                state_path.write_text(json.dumps(measured, indent=1) + "\n")
                second = f", {m['steps2']} steps: run {m['run2_s']:.2f} s" if "steps2" in m else ""
                print(f"{b.id}: {m['members']} members x {m['steps']} steps, up to {m['max_states']} states: "
                      f"compile {m['compile_s']:.1f} s, run {m['run_s']:.2f} s{second}, CPU {m['cpu_s']:.1f} s",
                      file=sys.stderr, flush=True)
    rows = extrapolate(full_batches, measured, args.scaling)
    done = [r for r in rows if r["run_s"] is not None]
    result = dict(full=dict(FULL, seeds=len(FULL["seeds"]), sets=list(settings)), scaling=args.scaling,
                  measured=measured,
                  batches=rows, run_s=sum(r["run_s"] for r in done), compile_s=sum(r["compile_s"] for r in done),
                  unmeasured_agents=sorted({r["agent"] for r in rows if r["run_s"] is None}))
    (work / "wall_time.json").write_text(json.dumps(result, indent=1) + "\n")
    print(f"full run: {result['run_s'] / 3600:.1f} h running + {result['compile_s'] / 3600:.2f} h compiling "
          f"({len(done)} of {len(rows)} batches; no measurement for {result['unmeasured_agents']})", file=sys.stderr)
    _common.publish(NAME, "Benchmark wall time", body(result, args), args, argv)
    print(compilation.time_report(time.perf_counter() - t_script, compile_stats.snapshot(), cache_folder),
          file=sys.stderr)
    return 0


def body(result: dict, args: argparse.Namespace) -> list[str]:
    """The table: the extrapolated hours of the full run per setting and agent, and their total."""
    full = result["full"]
    lines = [
        f"The full tabular benchmark ({len(full['sets'])} settings, {full['seeds']} seeds, {full['n_steps']:,} steps, "
        f"indicators every {full['log_period']} steps, {full['n_buckets']} size buckets) extrapolated from "
        f"{len(result['measured'])} measured batches ({args.seeds} seeds, steps {' and '.join(map(str, args.steps))}, "
        f"buckets: {args.which}; scaling per {result['scaling']}).",
        "",
        "| setting | agent | batches | members | running h | compiling h |",
        "|---|---|---|---|---|---|",
    ]
    groups: dict = {}
    for r in result["batches"]:
        groups.setdefault((r["set"], r["agent"]), []).append(r)
    for (set_name, agent), rows in groups.items():
        known = [r for r in rows if r["run_s"] is not None]
        run_h = f"{sum(r['run_s'] for r in known) / 3600:.2f}" if known else "not measured"
        comp_h = f"{sum(r['compile_s'] for r in known) / 3600:.2f}" if known else ""
        lines.append(f"| {set_name} | {agent} | {len(rows)} | {sum(r['members'] for r in rows)} | {run_h} | {comp_h} |")
    lines.append(f"| all | | {len(result['batches'])} | {sum(r['members'] for r in result['batches'])} | "
                 f"{result['run_s'] / 3600:.2f} | {result['compile_s'] / 3600:.2f} |")
    return lines


if __name__ == "__main__":
    sys.exit(main())
