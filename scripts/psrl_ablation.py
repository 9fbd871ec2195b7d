"""Ablation of PSRL continuous's reference mode: which of its two differences from the published algorithm makes it
learn faster on a benchmark MDP (docs/benchmark.md §13).

The reference mode (``psrl_continuous@colosseum``) differs from the paper's rules in two places
(``agents/psrl_continuous.py``): the candidate kernels of the optimistic sampling (deviation over ``N(s, a, s')``, one
shared state per candidate, ``sum + 1e-5`` normalisation) and the extended actions' rewards (action ``j = a psi + k``
gets the reward of real action ``j mod A``). This script runs the four combinations with the reference's
hyperparameters on one MDP of a benchmark set, seeds 0..n-1, through the runner with the benchmark's member keys, and
prints each seed's final normalised cumulative regret (the benchmark's ``members.csv`` column).

    python scripts/psrl_ablation.py --set "continuous communicating" --mdp RiverSwim/prms_1 --steps 40000 --seeds 3
"""

from __future__ import annotations

import os

if __name__ == "__main__" and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (  # one lockstep loop per core, as scripts/run_benchmark.py runs
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={os.cpu_count() or 1}"
    ).strip()

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import functools  # noqa: E402
import json  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from agents import psrl_continuous as pc  # noqa: E402
from hardness.benchmark import hparams as hp_sources  # noqa: E402
from hardness.benchmark import sets  # noqa: E402
from jaxmdp.experiment import runner  # noqa: E402

#: (name, candidate kernels' rule, extended rewards' rule)
COMBINATIONS = (
    ("paper", "paper", "paper"),
    ("reference kernels, paper rewards", "colosseum", "paper"),
    ("paper kernels, reference rewards", "paper", "colosseum"),
    ("reference mode", "colosseum", "colosseum"),
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--set", default="continuous communicating")
    ap.add_argument("--mdp", default="RiverSwim/prms_1", help="label of an MDP of the set")
    ap.add_argument("--steps", type=int, default=40_000)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--log-period", type=int, default=100)
    ap.add_argument("--out", type=Path, default=Path("results/psrl_ablation.json"))
    args = ap.parse_args()
    inst = sets.instance(args.set, args.mdp)
    mdp = inst.build(0)
    base = hp_sources.hparams_for(pc.PSRL_CONTINUOUS.name, "reference", "colosseum")
    (hp,) = hp_sources.fit_static_sizes(pc.PSRL_CONTINUOUS.name, [base], [mdp])
    rows = {}
    for name, kernels, rewards in COMBINATIONS:
        agent = dataclasses.replace(pc.PSRL_CONTINUOUS, name=f"psrl_continuous[{name}]",
                                    plan=functools.partial(pc.plan, variant=kernels, reward_variant=rewards))
        res = runner.run(agent, runner.product([mdp], [hp], seeds=range(args.seeds)), args.steps,
                         log_period=args.log_period, n_records=10)
        final = np.asarray(res.column("normalized_cumulative_regret")[-1], float)
        rows[name] = dict(kernels=kernels, rewards=rewards, normalized_cumulative_regret=final.round(1).tolist(),
                          run_s=round(res.run_s, 1), compile_s=round(res.compile_s, 1))
        print(f"{name:34s} {' '.join(f'{x:10.1f}' for x in final)}   (run {res.run_s:.0f} s)", flush=True)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(dict(set=args.set, mdp=args.mdp, steps=args.steps, rows=rows), indent=1) + "\n")


if __name__ == "__main__":
    main()
