"""Benchmark: one agent on one setting of the full benchmark, its MDPs split into ``n_buckets`` size buckets against
the agent's own count (:data:`hardness.benchmark.run.PLANNING_BUCKETS`), every bucket of both splits run as the
benchmark runs it (:func:`scripts.benchmark_wall_time.measure`: one ``run_benchmark`` batch per bucket, reference
hyperparameters, indicators every 100 steps) at two step counts, in one process.

Per bucket: members, largest state count, compile and run seconds; per split: the sums. The difference of the two
step counts is the cost of the steps between them; the longer run's total also charges each batch's fixed cost, which
the finer split pays more often. (Two splits share the programs of buckets with the same shapes: the second compiles
those from the cache.)

    python scripts/bench_bucket_split.py --set "episodic ergodic" --agent psrl_episodic --seeds 4 --out DIR
"""

from __future__ import annotations

import os

if __name__ == "__main__" and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (  # one program per core, as the benchmark runs (set before JAX starts)
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={os.cpu_count() or 1}"
    ).strip()

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
import benchmark_wall_time as bwt  # noqa: E402

from hardness.benchmark import run  # noqa: E402
from jaxmdp.experiment import compilation  # noqa: E402


def buckets(set_name: str, agent: str, agent_buckets: dict | None) -> list[list[str]]:
    """The MDP labels of each of ``agent``'s batches on ``set_name`` (``agent_buckets=None``: the default counts)."""
    kw = {} if agent_buckets is None else dict(agent_buckets=agent_buckets)
    _, batches = run.plan(run.RunConfig(sets=(set_name,), agents=(agent,), seeds=(0,), hparams="reference", **kw))
    return [sorted({label for label, _ in b.members}) for b in batches]


def main(argv: list[str] | None = None) -> list[dict]:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--set", required=True, help="a benchmark setting, e.g. 'episodic ergodic'")
    p.add_argument("--agent", required=True, help="an agent of that setting")
    p.add_argument("--seeds", type=int, default=4, help="seeds per MDP (%(default)s)")
    p.add_argument("--steps", type=int, nargs=2, default=[2000, 4000], metavar="N", help="two step counts")
    p.add_argument("--out", type=Path, required=True, help="folder for the runs and rows.json")
    compilation.add_cache_flag(p)
    args = p.parse_args(argv)
    compilation.setup_compilation(args.no_compile_cache)
    count = run.RunConfig(sets=(args.set,)).buckets(args.agent)
    if count == run.RunConfig.n_buckets:
        p.error(f"{args.agent} runs on the default {count} buckets: no other split to compare")
    rows = []
    for split, groups in ((f"{run.RunConfig.n_buckets} buckets", buckets(args.set, args.agent, {})),
                          (f"{count} buckets", buckets(args.set, args.agent, None))):
        for i, labels in enumerate(groups):
            m1, m2 = (bwt.measure(args.set, args.agent, labels, args.seeds, n, args.out / f"{split[0]}_b{i}_{n}")
                      for n in args.steps)
            row = dict(split=split, bucket=f"b{i}", mdps=len(labels), members=m1["members"],
                       max_states=m1["max_states"], compile_s=m1["compile_s"], run1_s=m1["run_s"], run2_s=m2["run_s"])
            rows.append(row)
            print(json.dumps(row), flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "rows.json").write_text(json.dumps(dict(command=" ".join(sys.argv), rows=rows), indent=1))
    for split in dict.fromkeys(r["split"] for r in rows):
        rs = [r for r in rows if r["split"] == split]
        print(f"{split}: run s {sum(r['run1_s'] for r in rs):.2f} / {sum(r['run2_s'] for r in rs):.2f} "
              f"({args.steps[0]} / {args.steps[1]} steps), steps between: "
              f"{sum(r['run2_s'] - r['run1_s'] for r in rs):.2f} s, compile {sum(r['compile_s'] for r in rs):.1f} s")
    return rows


if __name__ == "__main__":
    main()
