"""Benchmark: planning a lockstep batch whole, or in rounds of planning slots, when most of its members ask at once.

The runner's planning step (:func:`jaxmdp.experiment.planning.plan_due`) plans the members that asked in rounds of
``plan_slots``; an agent's ``whole_batch_plans`` (members) and ``whole_batch_bytes`` (bytes of agent state) bound
the batch that it instead plans whole, in one ``vmap``, when more than half its members ask. For each agent and batch
size this script runs the agent twice, as ``whole`` (both ``None``: the whole-batch copy of ``plan`` compiled beside
the rounds) and as ``rounds`` (``whole_batch_plans=0``: rounds only), whatever the agent's own setting, on one host
device (one shard, so a shard is the batch), and reports the cold compile time and the best of ``--repeats`` warm
runs. The two must give the same records and final agent states bit for bit (the script stops otherwise).

Grids: ``sync``, one episodic MiniGridEmpty (size 5) with every member's episodes ending at the same steps (one MDP,
many seeds, as in a hyperparameter search); ``sync400``, the same with MiniGridEmpty size 10 (400 states, as the
benchmark's largest episodic MDPs); ``mixed``, three MiniGridEmpty sizes (4, 5, 6: horizons 11, 13, 15) in
one stack, as in a benchmark batch, where at most a third of the members ask at once after the first step;
``river``, continuous RiverSwim-10 (UCRL2 and continuous PSRL, whose epochs end member by member).

    python scripts/bench_whole_batch_plans.py
    python scripts/bench_whole_batch_plans.py --cases psrl_episodic:sync --members 16,256 --repeats 3

Appends a section to ``docs/benchmarks/bench_whole_batch_plans.md`` unless ``--doc ''``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

DEFAULT_CASES = "psrl_episodic:sync,psrl_episodic:mixed,ucrl2:river,psrl_continuous:river"
STEPS = {"sync": 600, "sync400": 600, "mixed": 600, "river": 3000}


def _grid(kind: str, members: int, hparams):
    import jaxmdp
    from jaxmdp.experiment import runner

    if kind in ("sync", "sync400"):
        mdps = [jaxmdp.make("MiniGridEmpty", episodic=True, seed=0, size=5 if kind == "sync" else 10)]
    elif kind == "mixed":
        mdps = [jaxmdp.make("MiniGridEmpty", episodic=True, seed=0, size=n) for n in (4, 5, 6)]
    else:
        mdps = [jaxmdp.make("RiverSwim", episodic=False, seed=0, size=10, randomize_actions=False, p_lazy=0.1)]
    if members % len(mdps):
        raise SystemExit(f"--members: {members} is not a multiple of the {len(mdps)} MDPs of grid {kind!r}")
    return runner.product(mdps, [hparams], seeds=list(range(members // len(mdps))))


def measure(name: str, kind: str, members: int, repeats: int) -> list[dict]:
    """Compile and warm run seconds of the agent planning ``whole`` and in ``rounds`` (the same records and final
    agent states asserted)."""
    import jax
    import numpy as np

    import agents
    from jaxmdp.experiment import runner

    base = agents.get(name)
    grid = _grid(kind, members, base.default_hparams)
    rows, values = [], None
    for mode, limit in (("whole", None), ("rounds", 0)):
        agent = dataclasses.replace(base, whole_batch_plans=limit, whole_batch_bytes=None)
        # One shard whatever XLA_FLAGS says, so that the batch is the shard that whole_batch_plans bounds.
        run = lambda: runner.run(agent, grid, STEPS[kind], log_period=100, n_records=5, shards=1)  # noqa: E731
        first = run()
        best = float("inf")
        for _ in range(repeats):
            t = time.perf_counter()
            res = run()
            best = min(best, time.perf_counter() - t)
        v = [np.asarray(res.values)] + [np.asarray(x) for x in jax.tree.leaves(res.agent_state)]
        if values is not None and not all(np.array_equal(x, y) for x, y in zip(v, values)):
            raise SystemExit(f"{name} on {kind} with {members} members: whole and rounds gave different records or "
                             "final agent states")
        values = v
        rows.append({"agent": name, "grid": kind, "members": members, "mode": mode, "steps": STEPS[kind],
                     "compile_s": first.compile_s, "run_s": best})
        print(f"{name:16s} {kind:6s} {members:4d} {mode:6s} compile {first.compile_s:5.1f} s  run {best:6.2f} s",
              flush=True)
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", default=DEFAULT_CASES,
                   help="comma-separated agent:grid pairs (grids: sync, sync400, mixed, river)")
    p.add_argument("--members", default="24,48,96,192", help="comma-separated batch sizes")
    p.add_argument("--repeats", type=int, default=2, help="warm runs per measurement (best kept)")
    p.add_argument("--doc", default=str(ROOT / "docs" / "benchmarks" / "bench_whole_batch_plans.md"),
                   help="Markdown report to append to ('' for none)")
    args = p.parse_args()
    if args.repeats < 1:
        p.error("--repeats must be at least 1")
    cases = [c.split(":") for c in args.cases.split(",")]
    if any(len(c) != 2 or c[1] not in STEPS for c in cases):
        p.error(f"--cases: agent:grid pairs with grid one of {sorted(STEPS)}; got {args.cases!r}")
    rows = [r for name, kind in cases for m in args.members.split(",") for r in measure(name, kind, int(m),
                                                                                         args.repeats)]
    if args.doc:
        from scripts.bench_doc import append_section

        body = ["| agent | grid | members | steps | whole: compile s | whole: run s | rounds: compile s | "
                "rounds: run s | rounds / whole (run) |", "|---|---|---|---|---|---|---|---|---|"]
        for w, r in zip(rows[::2], rows[1::2]):
            body.append(f"| {w['agent']} | {w['grid']} | {w['members']} | {w['steps']} | {w['compile_s']:.1f} | "
                        f"{w['run_s']:.2f} | {r['compile_s']:.1f} | {r['run_s']:.2f} | "
                        f"{r['run_s'] / w['run_s']:.2f}x |")
        title = "Planning a batch whole or in rounds (`Agent.whole_batch_plans`, `whole_batch_bytes`)"
        append_section(args.doc, title, None, body)
        print(f"appended to {args.doc}")


if __name__ == "__main__":
    main()
