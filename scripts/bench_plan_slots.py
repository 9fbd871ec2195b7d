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

DEFAULT_BATCHES = (
    "episodic_ergodic.psrl_episodic.b1",  # 108 states, 80 members
    "episodic_ergodic.psrl_episodic.b2",  # 256 states, 80 members
    "episodic_ergodic.psrl_episodic.b6",  # 400 states, 40 members
    "episodic_communicating.psrl_episodic.b5",  # 400 states, 100 members
)
DEFAULT_DOC = ROOT / "docs" / "benchmarks" / "bench_plan_slots.md"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--batches", nargs="+", default=list(DEFAULT_BATCHES), help="batch ids of the full plan")
    p.add_argument("--slots", nargs="+", default=["rule", "uncapped", "1", "2"],
                   help="rule, uncapped or a slot count per shard (%(default)s)")
    p.add_argument("--steps", type=int, default=2400, help="steps of every run (%(default)s)")
    p.add_argument("--repeats", type=int, default=2, help="interleaved runs of each value (%(default)s)")
    p.add_argument("--doc", default=str(DEFAULT_DOC), help="Markdown file to append to ('' for none)")
    return p


def measure(batch_id: str, slot_values: list[str], steps: int, repeats: int) -> list[str]:
    """Table rows (one per slot value) for one batch: slots per shard, best run seconds, agent-steps/s and the time
    against ``uncapped``; raises if two values give different records."""
    import jax
    import numpy as np

    import agents as agent_registry
    from hardness.benchmark import run as bench
    from jaxmdp.experiment import runner
    from jaxmdp.experiment.planning import default_plan_slots

    config = bench.RunConfig(sets=("episodic ergodic", "episodic communicating", "continuous ergodic",
                                   "continuous communicating"))
    _, batches = bench.plan(config)
    by_id = {b.id: b for b in batches}
    if batch_id not in by_id:
        raise SystemExit(f"--batches: no batch {batch_id!r} in the full plan; e.g. {sorted(by_id)[:3]}")
    batch = by_id[batch_id]
    agent = agent_registry.get(batch.agent, config.agent_variant)
    grid = bench.batch_grid(batch, config)
    shards = max(d for d in range(1, jax.local_device_count() + 1) if grid.n_members % d == 0)
    per_shard = grid.n_members // shards
    rule = _rule_slots(agent, grid, per_shard)
    chosen = {"rule": None, "uncapped": default_plan_slots(per_shard)}
    best, records, slots_of = {}, {}, {}
    for name in slot_values:
        value = chosen[name] if name in chosen else int(name)
        slots_of[name] = rule if value is None else value
    for _ in range(repeats):
        for name in slot_values:
            value = chosen[name] if name in chosen else int(name)
            result = runner.run(agent, grid, steps, log_period=100, n_records=10, plan_slots=value)
            best[name] = min(best.get(name, float("inf")), result.run_s)
            digest = np.asarray(result.values).tobytes()
            if records.setdefault("ref", digest) != digest:
                raise SystemExit(f"{batch_id}: slots {name} gave different records")
            print(f"  {batch_id} slots {name} ({slots_of[name]}): {result.run_s:.2f} s", flush=True)
    base = best.get("uncapped")
    rows = []
    for name in slot_values:
        ratio = f"{base / best[name]:.2f}x" if base else ""
        rows.append(f"| {batch_id} | {grid.n_members} ({shards} x {per_shard}) | {name} | {slots_of[name]} | "
                    f"{best[name]:.2f} | {grid.n_members * steps / best[name]:,.0f} | {ratio} |")
    return rows


def _rule_slots(agent, grid, per_shard: int) -> int:
    """The slots the runner picks for a shard of ``per_shard`` members of ``grid`` (its agent states' shapes)."""
    import jax

    from jaxmdp.experiment import runner
    from jaxmdp.experiment.agent_interface import spec_of
    from jaxmdp.experiment.members import member_mdp

    hp = jax.tree.map(lambda x: x[0], grid.hparams)
    one = jax.eval_shape(lambda: agent.init(jax.random.key(0), spec_of(member_mdp(grid.mdps, 0), 1), hp))
    states = jax.tree.map(lambda x: jax.ShapeDtypeStruct((per_shard,) + x.shape, x.dtype), one)
    return runner.plan_slots_for(agent, states)


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    for name in args.slots:
        if name not in ("rule", "uncapped") and not (name.isdigit() and int(name) > 0):
            raise SystemExit(f"--slots: {name!r} is not rule, uncapped or a positive integer")
    rows = []
    for batch_id in args.batches:
        rows += measure(batch_id, args.slots, args.steps, args.repeats)
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
