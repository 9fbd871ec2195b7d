"""Tune the tabular agents by random search (paper App. F; :mod:`hardness.benchmark.search`) and write the winners,
with their provenance, to the tuned file the benchmark reads (``hardness/benchmark/tuned_hparams.json``).

Defaults are the reference's code-default budget (50 candidates drawn with seeds 42, 43, ..., 5 MDPs per family from
every family's sampler with seed 42, seeds 0-2, 250 000 steps), plus the reference's cached values as one more
candidate. Pass smaller numbers for a reduced run (the file records the budget and marks it reduced).

    python scripts/tune_agents.py                                             # every tabular agent, full budget
    python scripts/tune_agents.py --agents ucrl2 --steps 20000 --candidates 8 --mdps-per-family 1 --seeds 1

The file is rewritten after every agent, and every size bucket of a search keeps a CSV and a checkpoint in
``--work-dir`` (default ``results/tuning``, a folder per agent and budget), so a killed run started again with the
same arguments resumes: agents whose entry in ``--out`` already has this budget are skipped (``--redo`` reruns them)
and an unfinished search continues from its last checkpoint. Each entry records the search's wall time (``wall_s``,
building the MDPs, compiling and running).
"""

from __future__ import annotations

import os

if __name__ == "__main__" and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    # One lockstep loop per core: the runner shards the members over the host devices (set before JAX starts).
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={os.cpu_count() or 1}"
    ).strip()

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from agents.search_spaces import SEARCH_SPACES  # noqa: E402
from hardness.benchmark import hparams, search  # noqa: E402

DEFAULT = search.Budget()


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--agents", nargs="+", default=list(SEARCH_SPACES), choices=list(SEARCH_SPACES),
                   help="default: every agent with a search space")
    p.add_argument("--steps", type=int, default=DEFAULT.n_steps, help="steps per run (%(default)s)")
    p.add_argument("--candidates", type=int, default=DEFAULT.n_candidates, help="sampled candidates (%(default)s)")
    p.add_argument("--mdps-per-family", type=int, default=DEFAULT.n_per_family, help="%(default)s")
    p.add_argument("--seeds", type=int, default=DEFAULT.n_seeds, help="seeds 0..N-1 (%(default)s)")
    p.add_argument("--log-period", type=int, default=DEFAULT.log_period, help="%(default)s")
    p.add_argument("--max-states", type=int, default=None, help="leave out sampled MDPs with more states")
    p.add_argument("--no-reference-candidate", action="store_true",
                   help="do not add the reference's cached values as a candidate")
    p.add_argument("--buckets", type=int, default=4, help="size buckets per search (%(default)s)")
    p.add_argument("--note", default="", help="a note stored with each entry")
    p.add_argument("--out", type=Path, default=hparams.TUNED_FILE, help="tuned file (default: the shipped one)")
    p.add_argument("--work-dir", type=Path, default=Path("results/tuning"),
                   help="runner CSVs and checkpoints, one folder per agent, to resume from (%(default)s)")
    p.add_argument("--redo", action="store_true", help="rerun agents already tuned with this budget in --out")
    return p


def main(argv: list[str] | None = None) -> dict:
    args = build_parser().parse_args(argv)
    budget = search.Budget(n_steps=args.steps, n_candidates=args.candidates, n_per_family=args.mdps_per_family,
                           n_seeds=args.seeds, log_period=args.log_period, max_states=args.max_states,
                           include_reference=not args.no_reference_candidate)
    done = json.loads(args.out.read_text()).get("agents", {}) if args.out.exists() and not args.redo else {}
    entries = {}
    for name in args.agents:
        if name in done and _same_budget(done[name], budget):
            print(f"{name}: already tuned with this budget in {args.out}; skipped (--redo reruns it)",
                  file=sys.stderr, flush=True)
            continue
        print(f"tuning {name}: {budget}", file=sys.stderr, flush=True)
        start = time.perf_counter()
        try:
            result = search.search(name, budget, n_buckets=args.buckets, progress=True,
                                   work_dir=args.work_dir / name / _slug(budget) if args.work_dir else None)
        except ValueError as err:
            raise SystemExit(f"tune_agents: {err}") from None
        entries[name] = search.provenance(result, budget, note=args.note)
        entries[name]["wall_s"] = round(time.perf_counter() - start, 1)
        search.write_tuned(args.out, {name: entries[name]})  # after every agent, so an interruption keeps it
        e = entries[name]
        print(f"  {name}: winner {e['winner']} {e['values']}, objective per step {e['objective_per_step']:.4f} "
              f"(run {e['run_s']} s, compile {e['compile_s']} s, wall {e['wall_s']} s)", file=sys.stderr, flush=True)
    return entries


def _slug(budget: search.Budget) -> str:
    """A folder name for one budget, so checkpoints of different budgets never meet."""
    return "-".join(f"{k}{v}" for k, v in dataclasses.asdict(budget).items()).replace("_", "")


def _same_budget(entry: dict, budget: search.Budget) -> bool:
    """Whether a tuned-file entry was searched with ``budget`` (every field of :class:`search.Budget`)."""
    return all(entry.get("budget", {}).get(k) == v for k, v in dataclasses.asdict(budget).items())


if __name__ == "__main__":
    from jaxmdp.experiment.compilation import enable_compilation_cache

    enable_compilation_cache()  # the persistent compilation cache (JAXMDP_COMPILATION_CACHE=0: off)
    main()
    sys.exit(0)
