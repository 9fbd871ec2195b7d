"""Benchmark: the random agent in the lockstep runner with its policy declared fixed (``Agent.fixed_policy``: evaluated
at the first log only) against the same agent without the declaration (its ``[H, S, A]`` or ``[S, A]`` policy built
and compared with the previous log's at every log), on the benchmark MDPs of ``scripts/bench_agents.py``: 1 024
seeds, 4 000 steps, indicators every 100 steps, 2 host devices, in one process, interleaved, best of ``--repeats``.
The records are compared too (they must be identical).

    python scripts/bench_fixed_policy.py

Writes a section to ``docs/benchmarks/bench_fixed_policy.md`` (with the command) unless ``--doc ''``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path

# The runner shards members over one host device per core (as scripts/bench_agents.py); set before jax is imported.
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import numpy as np  # noqa: E402

import agents  # noqa: E402
import jaxmdp  # noqa: E402
from bench_agents import BENCH_MDPS  # noqa: E402
from bench_doc import append_section  # noqa: E402
from jaxmdp.experiment import runner  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=1024)
    p.add_argument("--steps", type=int, default=4000)
    p.add_argument("--repeats", type=int, default=4, help="interleaved timed runs of each (best is reported)")
    p.add_argument("--doc", default=str(ROOT / "docs" / "benchmarks" / "bench_fixed_policy.md"))
    args = p.parse_args(argv)
    rows = ["| setting | MDP | compared at every log | fixed | time ratio | same records |", "|---|---|---|---|---|---|"]
    for episodic in (True, False):
        fixed = agents.get("random_episodic" if episodic else "random_continuous")
        runs = {"compared": dataclasses.replace(fixed, fixed_policy=False), "fixed": fixed}
        for family in ("RiverSwim", "Taxi", "MiniGridEmpty"):
            mdp = jaxmdp.make(family, episodic=episodic, seed=0, **BENCH_MDPS[(family, episodic)])
            grid = runner.product([mdp], [fixed.default_hparams], seeds=range(args.seeds))
            best, values = {}, {}
            for tag, agent in runs.items():  # compile
                runner.run(agent, grid, args.steps, log_period=100, n_records=10)
            for _ in range(args.repeats):
                for tag, agent in runs.items():
                    res = runner.run(agent, grid, args.steps, log_period=100, n_records=10)
                    best[tag] = min(best.get(tag, np.inf), res.run_s)
                    values[tag] = res.values
            rate = {k: f"{args.seeds * args.steps / v / 1e6:.2f} M agent-steps/s" for k, v in best.items()}
            same = bool(np.array_equal(values["compared"], values["fixed"]))
            rows.append(f"| {'episodic' if episodic else 'continuous'} | {family} | {rate['compared']} | "
                        f"{rate['fixed']} | {best['fixed'] / best['compared']:.2f}x | {same} |")
            print(rows[-1], flush=True)
    if args.doc:
        append_section(args.doc, "The random agent's fixed policy: evaluated once, never compared", argv, rows)


if __name__ == "__main__":
    main()
