"""Profile what a log costs a continuous model-based agent in the runner: its policy estimate and the indicators'
exact evaluation of that policy (paper App. A.1; issue "Performance", item 2).

The agent (default PSRL continuous) runs through :func:`jaxmdp.experiment.runner.run` on ``--seeds`` seeds of one MDP
of the continuous benchmark sets, with its planning switched off (``needs_plan`` always False: the plans are
profiled by ``profile_continuous_plans.py``), indicators every 100 steps and no checkpoint, in three modes:

* ``const``: the policy estimate replaced by a constant policy (so no evaluation after the first log either): the
  steps alone;
* ``noeval``: the agent's own policy estimate, the indicators' evaluation replaced by the cached values;
* ``full``: both.

Each mode runs ``N1`` and ``N2`` steps (default 2 000 and 4 000: 20 runner chunks each, so the per-chunk costs cancel)
and reports ``(run2 - run1) / (members x logs between them)``: milliseconds per member and log. ``noeval - const`` is
the policy estimate, ``full - noeval`` the evaluation.

    python scripts/profile_log_cost.py --label MiniGridRooms/prms_1 --seeds 20
"""

from __future__ import annotations

import argparse
import dataclasses

import jax.numpy as jnp

import agents
from agents import psrl_continuous
from hardness.benchmark import sets
from jaxmdp.experiment import compilation, runner

MODES = ("const", "noeval", "full")


def _variant(agent: agents.Agent, mode: str) -> agents.Agent:
    """The agent with planning off and, for ``const``, a constant policy estimate (action 0 everywhere)."""
    agent = dataclasses.replace(agent, needs_plan=lambda state: jnp.zeros((), bool))
    if mode == "const":
        agent = dataclasses.replace(agent, greedy_actions=None,
                                    policy=lambda state: jnp.zeros(state.Q.shape, state.Q.dtype).at[..., 0].set(1.0))
    return agent


def main(argv: list[str] | None = None) -> dict[str, float]:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--agent", default="psrl_continuous", choices=["psrl_continuous", "ucrl2"])
    p.add_argument("--label", default="MiniGridRooms/prms_1", help="MDP of a continuous benchmark set")
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--steps", type=int, nargs=2, default=[2000, 4000], metavar=("N1", "N2"))
    p.add_argument("--modes", nargs="+", default=list(MODES), choices=MODES)
    compilation.add_cache_flag(p)
    args = p.parse_args(argv)
    compilation.setup_compilation(args.no_compile_cache)
    base = agents.get(args.agent)
    inst = next(i for s in ("continuous ergodic", "continuous communicating") for i in sets.instances(s)
                if i.label == args.label)
    mdp = inst.build(0)
    hp = base.default_hparams
    if args.agent == "psrl_continuous":  # the plan's buffer at the MDP's own psi, as the benchmark sizes it
        hp = hp.replace(max_psi=psrl_continuous.psi(hp, mdp.n_states, mdp.n_actions))
    grid = runner.product([mdp], [hp], seeds=list(range(args.seeds)))
    evaluate = runner._evaluate_changed
    logs = (args.steps[1] - args.steps[0]) // 100
    out = {}
    try:
        for mode in args.modes:
            runner._evaluate_changed = (lambda *a, **k: a[4]) if mode == "noeval" else evaluate  # a[4]: the cache
            agent = _variant(base, mode)
            runs = [runner.run(agent, grid, n, log_period=100) for n in args.steps]
            out[mode] = 1e3 * (runs[1].run_s - runs[0].run_s) / (args.seeds * logs)
            print(f"{args.agent} {args.label} ({mdp.n_states} states, {args.seeds} seeds) {mode}: run "
                  f"{runs[0].run_s:.2f} / {runs[1].run_s:.2f} s for {args.steps[0]} / {args.steps[1]} steps, compile "
                  f"{runs[0].compile_s:.1f} s: {out[mode]:.2f} ms per member and log", flush=True)
    finally:
        runner._evaluate_changed = evaluate
    return out


if __name__ == "__main__":
    main()
