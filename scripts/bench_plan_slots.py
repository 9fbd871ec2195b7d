"""Benchmark: the planning slots of the runner's rounds, on the benchmark's own batches.

The runner plans the members that ask in rounds of ``plan_slots`` (:func:`jaxmdp.experiment.planning.plan_due`); the
results do not depend on the slots, only the time does. Left to itself the runner takes ``ceil(members / 16)`` slots
per shard, capped on a CPU by ``Agent.plan_slot_bytes`` over one member's agent state
(:func:`jaxmdp.experiment.runner.plan_slots_for`). For each batch of the full benchmark's plan (20 seeds, the four
settings, :func:`hardness.benchmark.run.plan`) named by ``--batches``, this script runs ``--steps`` steps with each
``--slots`` value in turn, ``--repeats`` times interleaved, as the benchmark runs it (one shard per core), and reports
the best run seconds (compilation excluded). ``rule`` is the runner's own choice (``plan_slots=None``), ``uncapped``
the rule without the byte cap, an integer that many slots. Every value must give the same records bit for bit (the
script stops otherwise).

    python scripts/bench_plan_slots.py
    python scripts/bench_plan_slots.py --batches episodic_communicating.psrl_episodic.b5 --slots rule uncapped 1 2

Appends a section to ``docs/benchmarks/bench_plan_slots.md`` unless ``--doc ''``.
"""

from __future__ import annotations

import os

if __name__ == "__main__" and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    # One lockstep loop per core, as scripts/run_benchmark.py runs (set before JAX starts).
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={os.cpu_count() or 1}"
    ).strip()

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hardness.benchmark import run as bench  # noqa: E402

DEFAULT_BATCHES = (
    "episodic_ergodic.psrl_episodic.b1",  # 108 states, 80 members
    "episodic_ergodic.psrl_episodic.b2",  # 256 states, 80 members
    "episodic_ergodic.psrl_episodic.b6",  # 400 states, 40 members
    "episodic_communicating.psrl_episodic.b5",  # 400 states, 100 members
)
DEFAULT_DOC = ROOT / "docs" / "benchmarks" / "bench_plan_slots.md"
#: The full benchmark (20 seeds, the four settings): the batches named by ``--batches``.
FULL = bench.RunConfig(sets=("episodic ergodic", "episodic communicating", "continuous ergodic",
                             "continuous communicating"))


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--batches", nargs="+", default=list(DEFAULT_BATCHES), help="batch ids of the full plan")
    p.add_argument("--slots", nargs="+", default=["rule", "uncapped", "1", "2"],
                   help="rule, uncapped or a slot count per shard (%(default)s)")
    p.add_argument("--steps", type=int, default=2400, help="steps of every run (%(default)s)")
    p.add_argument("--repeats", type=int, default=2, help="interleaved runs of each value (%(default)s)")
    p.add_argument("--doc", default=str(DEFAULT_DOC), help="Markdown file to append to ('' for none)")
    return p


def measure(batch, slot_values: list[str], steps: int, repeats: int) -> list[str]:
    """Table rows (one per slot value) for one batch of the full plan: slots per shard, best run seconds,
    agent-steps/s and the time against ``uncapped``; stops if two values give different records."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    import agents as agent_registry
    from jaxmdp.experiment import runner
    from jaxmdp.experiment.agent_interface import spec_of
    from jaxmdp.experiment.members import member_mdp
    from jaxmdp.experiment.planning import default_plan_slots

    agent = agent_registry.get(batch.agent, FULL.agent_variant)
    grid = bench.batch_grid(batch, FULL)
    shards = max(d for d in range(1, jax.local_device_count() + 1) if grid.n_members % d == 0)
    per_shard = grid.n_members // shards
    # The slots the runner picks for a shard: its agent states' shapes (hyperparameters in float32, as it holds them).
    hp = jax.tree.map(lambda x: jnp.asarray(x[0]), grid.hparams)
    one = jax.eval_shape(lambda: agent.init(jax.random.key(0), spec_of(member_mdp(grid.mdps, 0), steps), hp))
    shard = jax.tree.map(lambda x: jax.ShapeDtypeStruct((per_shard,) + x.shape, x.dtype), one)
    values = {name: None if name == "rule" else default_plan_slots(per_shard) if name == "uncapped" else int(name)
              for name in slot_values}
    slots_of = {name: runner.plan_slots_for(agent, shard) if v is None else v for name, v in values.items()}
    best, reference = dict.fromkeys(values, float("inf")), None
    for _ in range(repeats):
        for name, value in values.items():
            result = runner.run(agent, grid, steps, log_period=100, n_records=10, plan_slots=value)
            best[name] = min(best[name], result.run_s)
            records = np.asarray(result.values).tobytes()
            if reference is not None and records != reference:
                raise SystemExit(f"{batch.id}: slots {name} gave different records")
            reference = records
            print(f"  {batch.id} slots {name} ({slots_of[name]}): {result.run_s:.2f} s", flush=True)
    base = best.get("uncapped")
    return [f"| {batch.id} | {grid.n_members} ({shards} x {per_shard}) | {name} | {slots_of[name]} | "
            f"{best[name]:.2f} | {grid.n_members * steps / best[name]:,.0f} | "
            f"{f'{base / best[name]:.2f}x' if base else ''} |" for name in values]


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    for name in args.slots:
        if name not in ("rule", "uncapped") and not (name.isdigit() and int(name) > 0):
            raise SystemExit(f"--slots: {name!r} is not rule, uncapped or a positive integer")
    by_id = {b.id: b for b in bench.plan(FULL)[1]}
    unknown = [b for b in args.batches if b not in by_id]
    if unknown:
        raise SystemExit(f"--batches: no batch {unknown} in the full plan; e.g. {sorted(by_id)[:3]}")
    rows = [row for batch_id in args.batches for row in measure(by_id[batch_id], args.slots, args.steps, args.repeats)]
    body = [
        f"{args.steps} steps a run, indicators every 100 steps, best of {args.repeats} interleaved runs; every value "
        "gave the same records bit for bit. `x`: the time of `uncapped` over this one's.",
        "",
        "| batch | members (shards x members) | slots | slots per shard | run s | agent-steps/s | x |",
        "|---|---|---|---|---|---|---|",
        *rows,
    ]
    print("\n".join(body))
    if args.doc:
        from bench_doc import append_section

        append_section(args.doc, "Planning slots per round (`Agent.plan_slot_bytes`)", argv, body)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
