"""What the indicator logs cost a continuous model-based agent in the runner: one MDP, planning switched off
(``needs_plan`` always False), ``--seeds`` members on one device, ``--steps`` steps, run once with a single log at
the end and once with a log every ``--log-period`` steps; the difference is the logs (the policy estimate and the
evaluation of the policies that changed). Each run is made twice and the second is reported (compiled).

Run it in two checkouts to compare them (docs/benchmarks/continuous_indicators.md, "Warm-started policy estimates"):

    PYTHONPATH=$PWD python scripts/bench_log_cost.py --agent psrl_continuous --label MiniGridRooms/prms_1
"""

from __future__ import annotations

import argparse

import agents
from agents import psrl_continuous
from continuous_plan_wall_time import no_planning  # scripts/ is on the path of a script run as python scripts/NAME.py
from hardness.benchmark import sets
from jaxmdp.experiment import runner


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--agent", default="psrl_continuous", choices=["psrl_continuous", "ucrl2"])
    ap.add_argument("--set", default="continuous ergodic")
    ap.add_argument("--label", default="MiniGridRooms/prms_1")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--steps", type=int, default=1300)
    ap.add_argument("--log-period", type=int, default=100)
    args = ap.parse_args(argv)
    mdp = sets.instance(args.set, args.label).build(0)
    base = agents.get(args.agent)
    agent = no_planning(base)
    hp = base.default_hparams
    if args.agent == "psrl_continuous":  # the plan's buffer at the MDP's own psi, as the benchmark sizes it
        hp = hp.replace(max_psi=psrl_continuous.psi(hp, mdp.n_states, mdp.n_actions))
    grid = runner.product([mdp], [hp], range(args.seeds))
    seconds = {}
    for period in (args.steps, args.log_period):
        for _ in range(2):
            res = runner.run(agent, grid, args.steps, log_period=period, n_records=1)
        seconds[period] = res.run_s
    logs = -(-args.steps // args.log_period)
    cost = (seconds[args.log_period] - seconds[args.steps]) / (logs - 1) / args.seeds
    print(f"{args.agent} on {args.label} ({mdp.n_states} states), {args.seeds} members, {args.steps} steps: "
          f"run {seconds[args.steps]:.2f} s with one log, {seconds[args.log_period]:.2f} s with {logs}; "
          f"{1e3 * cost:.1f} ms per member and log")


if __name__ == "__main__":
    main()
