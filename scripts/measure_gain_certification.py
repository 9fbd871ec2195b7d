"""Count how the runner's continuous indicators were evaluated: certified on the successor lists (and in how many
sweeps) or by the dense fallback, for one agent on the largest (or smallest) size bucket of a continuous benchmark
setting; docs/benchmarks/continuous_indicators.md.

The runner's :func:`~jaxmdp.experiment.indicators.policy_values` is wrapped with a host callback that records each
evaluation's ``(certified, sweeps)``; the batch runs through ``hardness.benchmark.run.run_benchmark`` as
``scripts/benchmark_wall_time.py`` runs it (its ``batches.csv`` has the run seconds).

    python scripts/measure_gain_certification.py --agent q_learning_continuous --seeds 20 --steps 500 --out DIR
"""

from __future__ import annotations

import os

if __name__ == "__main__" and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={os.cpu_count() or 1}"
    ).strip()

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from hardness.benchmark import run  # noqa: E402
from jaxmdp import dynamic_programming as dp  # noqa: E402
from jaxmdp.experiment import runner  # noqa: E402
from jaxmdp.experiment.indicators import policy_values  # noqa: E402


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--set", default="continuous ergodic", help="continuous benchmark setting (%(default)s)")
    p.add_argument("--agent", required=True)
    p.add_argument("--bucket", choices=["largest", "smallest"], default="largest")
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument("--refine", type=int, default=None,
                   help="at most this many refinement sweeps per refresh (default: successor_gain_bounds' "
                        "default)")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    records: list[tuple[bool, int]] = []

    def record(certified, sweeps):
        records.extend(zip(np.atleast_1d(np.asarray(certified)).tolist(), np.atleast_1d(np.asarray(sweeps)).tolist()))

    def counted(mdp, policy, iterative_sweeps=0):
        if mdp.episodic or iterative_sweeps <= 0:
            return policy_values(mdp, policy, iterative_sweeps)
        b = dp.successor_gain_bounds(mdp, policy, max_sweeps=iterative_sweeps, refine_sweeps=args.refine)
        jax.debug.callback(record, b.certified, b.sweeps)
        one_hot = policy if not jnp.issubdtype(policy.dtype, jnp.integer) else jax.nn.one_hot(policy, mdp.n_actions)
        return jax.lax.cond(b.certified, lambda: 0.5 * (b.lower + b.upper), lambda: dp.gain_vector(mdp, one_hot))

    runner.policy_values = counted
    full = run.RunConfig(sets=(args.set,), agents=(args.agent,), seeds=tuple(range(20)), n_steps=500_000,
                         log_period=100, hparams="reference", n_buckets=4)
    _, batches = run.plan(full)
    batch = batches[-1] if args.bucket == "largest" else batches[0]
    labels = sorted({m for m, _ in batch.members})
    config = run.RunConfig(sets=(args.set,), agents=(args.agent,), seeds=tuple(range(args.seeds)), n_steps=args.steps,
                           log_period=100, hparams="reference", n_buckets=1, only=tuple(labels))
    args.out.mkdir(parents=True, exist_ok=True)
    run.run_benchmark(config, args.out, progress=False, report=False)
    with open(args.out / "batches.csv") as f:
        (row,) = list(csv.DictReader(f))
    cert = [s for c, s in records if c]
    result = dict(set=args.set, agent=args.agent, bucket=batch.id, labels=labels, seeds=args.seeds, steps=args.steps,
                  refine=args.refine, run_s=float(row["run_s"]), compile_s=float(row["compile_s"]),
                  evaluations=len(records), certified=len(cert),
                  sweeps_hist={str(k): int(v) for k, v in zip(*np.unique(cert, return_counts=True))} if cert else {})
    (args.out / "certification.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result), file=sys.stderr)
    return result


if __name__ == "__main__":
    main()
