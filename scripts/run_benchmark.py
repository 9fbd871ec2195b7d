"""Run the Colosseum benchmark (paper §3.3, App. G) to completion and write its tables and figures.

Every (MDP, agent, seed) of the chosen sets runs all its steps (no wall-clock cut-off) in lockstep batches grouped by
size; results are written as each batch finishes, and running again on the same folder continues where it stopped
(finished batches are never redone; the final ``members.csv`` is the same byte for byte). See
:mod:`hardness.benchmark.run` for the output folder and :mod:`hardness.benchmark.report` for the report.

    python scripts/run_benchmark.py --quick --out results/benchmark_quick       # the quick-test sets, a few minutes
    python scripts/run_benchmark.py --settings episodic_ergodic --seeds 20 --steps 500000 --out results/benchmark
    python scripts/run_benchmark.py --settings continuous_ergodic --agents ucrl2 --hparams reference --out DIR
    python scripts/run_benchmark.py --quick --hparams reference --agent-variant colosseum --out DIR   # reference mode
    python scripts/run_benchmark.py --quick --hparams reference --agent-variant colosseum --indicators colosseum \
        --out DIR                                         # reference mode with the reference's regret indicators
    python scripts/run_benchmark.py --quick --emission StateInfo --agents dqn_episodic random_episodic --out DIR
"""

from __future__ import annotations

import os

if __name__ == "__main__" and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    # One lockstep loop per core: the runner shards the members over the host devices (set before JAX starts).
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={os.cpu_count() or 1}"
    ).strip()

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from hardness.benchmark import run, sets  # noqa: E402


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--settings", nargs="+", default=None, metavar="SET",
                   help=f"benchmark sets (default: the four settings); one of: {', '.join(sets.SET_NAMES)}")
    p.add_argument("--agents", nargs="+", default=None,
                   help="agents by registry name (default: every tabular agent of each set's type; --quick: all but "
                        "psrl_continuous; with --emission: every deep agent of the set's type and the random agent)")
    p.add_argument("--mdps", nargs="+", default=None, metavar="MDP",
                   help="keep only these MDPs of the sets: labels (RiverSwim/prms_0) or families (default: all)")
    p.add_argument("--seeds", type=int, default=None, help="number of seeds 0..N-1 (default 20; --quick 2)")
    p.add_argument("--steps", type=int, default=None, help="steps per run (default 500000; --quick "
                   f"{run.QUICK['n_steps']})")
    p.add_argument("--log-period", type=int, default=None,
                   help="steps between indicator logs (default 100; --quick: 1000 episodic, 500 continuous)")
    p.add_argument("--hparams", default="tuned",
                   help="tuned (hardness/benchmark/tuned_hparams.json), reference (the reference's cached values) "
                        "or a tuned-file path (default %(default)s)")
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
                   help="size buckets per set for every agent (default 4, and 8 for episodic PSRL, whose posterior "
                        "draws pay for the padding at every episode; --quick 1)")
    p.add_argument("--max-members", type=int, default=None,
                   help="members per runner call (default: a bucket, halved until it fits in memory)")
    p.add_argument("--memory-limit", type=float, default=None, metavar="GIB",
                   help="GiB a runner call may use (default: the memory available)")
    p.add_argument("--emission", default=None,
                   help="observe the MDPs through this emission map, for the deep agents: state_info (the reference's "
                        "StateInfo), one_hot (OneHotEncoding), image, tensor, linear_optimal, linear_random (default: "
                        "the states, tabular agents); with it the default agents are the deep agents and the random "
                        "agent")
    p.add_argument("--quick", action="store_true", help="the quick-test sets, 2 seeds, few steps")
    p.add_argument("--out", type=Path, required=True, help="output folder (reused to resume)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def config_from_args(args: argparse.Namespace) -> run.RunConfig:
    """The run's settings: ``--quick`` defaults (or the benchmark's), overridden by the options given."""
    base = dict(run.QUICK) if args.quick else dict(sets=sets.SETTINGS)
    if args.emission is not None:
        base.pop("agents", None)  # --quick's agents are tabular; with an emission: the deep agents and random
    given = dict(sets=tuple(args.settings) if args.settings else None,
                 agents=tuple(args.agents) if args.agents else None,
                 seeds=tuple(range(args.seeds)) if args.seeds is not None else None, n_steps=args.steps,
                 n_buckets=args.buckets, max_members=args.max_members, emission=args.emission,
                 only=tuple(args.mdps) if args.mdps else None,
                 memory_limit=None if args.memory_limit is None else int(args.memory_limit * 2**30))
    config = {**base, **{k: v for k, v in given.items() if v is not None}, "hparams": args.hparams,
              "agent_variant": args.agent_variant, "indicator_variant": args.indicators,
              "stop_when_converged": args.stop_when_converged}
    if args.buckets is not None:
        config.update(agent_buckets={})  # --buckets N: N for every agent
    if args.log_period is not None:
        config.update(log_period=args.log_period, log_periods={})
    return run.RunConfig(**config)


def main(argv: list[str] | None = None) -> run.RunSummary:
    args = build_parser().parse_args(argv)
    try:
        config = config_from_args(args)
        return run.run_benchmark(config, args.out, progress=not args.quiet)
    except ValueError as err:
        raise SystemExit(f"run_benchmark: {err}") from None


if __name__ == "__main__":
    from jaxmdp.experiment.compilation import enable_compilation_cache

    enable_compilation_cache()  # the persistent compilation cache (JAXMDP_COMPILATION_CACHE=0: off)
    main()
    sys.exit(0)
