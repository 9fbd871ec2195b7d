"""Steps per second of the model-based agents (PSRL episodic, PSRL continuous, UCRL2) on RiverSwim 25.

Drives each agent with the test interaction loop (``tests/agent_loop.py``: one ``lax.scan``, planning for the whole
batch under one ``lax.cond`` whenever any member asks) at several batch sizes (seeds), and splits the time:

* ``full``: the real loop;
* ``no_plan``: the same loop with ``needs_plan`` forced to False after the initial plan, i.e. acting, stepping the
  MDP and the per-step updates only;
* ``plan_share = 1 - no_plan / full`` and ``per_batch_plan_ms = (full - no_plan) / batch_plans``;
* ``chunked`` (with ``--plan-chunk C``): the real loop, but planning only the members that asked, gathered into
  sub-batches of ``C`` (what a runner could do; same results).

MDPs are the benchmark's RiverSwim 25 entries (benchmark.md §3: continuous communicating ``prms_0`` and episodic
communicating ``prms_0``). Compilation is excluded (AOT-compiled first) and each timing is the best of ``--repeats``.

    PYTHONPATH=$PWD python scripts/bench_planners.py                       # 1, 64, 1024 seeds, 2 000 steps
    PYTHONPATH=$PWD python scripts/bench_planners.py --seeds 1 64 --steps 20000
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp

import jaxmdp
from agents import AGENTS
from agents.psrl_continuous import psi

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from agent_loop import make_runner, seeds  # noqa: E402  (the test loop stands in for the experiment runner)


def river_swim_25(episodic: bool) -> jaxmdp.MDP:
    if episodic:
        return jaxmdp.make(
            "RiverSwim", episodic=True, seed=0, size=25, p_lazy=0.05, make_reward_stochastic=True,
            randomize_actions=False, optimal_distribution=jaxmdp.Beta(0.01, 0.11),
            sub_optimal_distribution=jaxmdp.Beta(12.4, 124.0), other_distribution=jaxmdp.Beta(12.4, 1249.0),
        ).strip()
    return jaxmdp.make(
        "RiverSwim", episodic=False, seed=0, size=25, p_lazy=0.1, make_reward_stochastic=True, randomize_actions=False
    ).strip()


def _best_time(fn, args, repeats):
    best = float("inf")
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - t0)
    return best, out


def bench(name, agent, hparams, mdp, batch, n_steps, repeats, plan_chunk=None):
    no_plan_agent = dataclasses.replace(agent, needs_plan=lambda state: jnp.zeros((), bool))
    keys = seeds(batch)
    row = dict(agent=name, seeds=batch, steps=n_steps, S=mdp.n_states, A=mdp.n_actions)
    variants = [("full", agent, None), ("no_plan", no_plan_agent, None)]
    if plan_chunk is not None and plan_chunk < batch:
        variants.append(("chunked", agent, plan_chunk))
        row["plan_chunk"] = plan_chunk
    for variant, ag, chunk in variants:
        run = make_runner(ag, n_steps, plan_chunk=chunk)
        t0 = time.perf_counter()
        compiled = run.lower(keys, mdp, hparams).compile()
        row[f"{variant}_compile_s"] = round(time.perf_counter() - t0, 2)
        seconds, res = _best_time(compiled, (keys, mdp, hparams), repeats)
        row[f"{variant}_s"] = round(seconds, 4)
        row[f"{variant}_steps_per_s"] = round(batch * n_steps / seconds, 1)
        if variant == "full":
            row["batch_plans"] = int(res.n_batch_plans)
            row["plans_per_member"] = float(jnp.mean(res.n_plans))
    row["plan_share"] = round(max(0.0, 1 - row["no_plan_s"] / row["full_s"]), 3)
    row["per_batch_plan_ms"] = round(1e3 * max(0.0, row["full_s"] - row["no_plan_s"]) / max(1, row["batch_plans"]), 3)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 64, 1024])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--agents", nargs="+", default=["psrl_episodic", "ucrl2", "psrl_continuous"])
    parser.add_argument("--plan-chunk", type=int, default=None, help="also time planning in sub-batches of this size")
    parser.add_argument("--out", type=Path, default=Path("results/bench_planners.json"))
    args = parser.parse_args()

    rows = []
    for name in args.agents:
        agent = AGENTS[name]
        mdp = river_swim_25(agent.episodic)
        hparams = agent.default_hparams
        if name == "psrl_continuous":  # a tight candidate buffer (psi = 2 here); the default 60 is the worst case
            hparams = hparams.replace(max_psi=psi(hparams, mdp.n_states, mdp.n_actions))
        for batch in args.seeds:
            row = bench(name, agent, hparams, mdp, batch, args.steps, args.repeats, args.plan_chunk)
            rows.append(row)
            print(
                f"{name:16s} seeds={batch:5d}  {row['full_steps_per_s']:>11.0f} steps/s  "
                f"(no planning {row['no_plan_steps_per_s']:>11.0f})  plan share {row['plan_share']:.2f}  "
                f"batch plans {row['batch_plans']:5d}/{args.steps}  {row['per_batch_plan_ms']:.3f} ms each"
                + (f"  chunked({row['plan_chunk']}) {row['chunked_steps_per_s']:.0f} steps/s" if "plan_chunk" in row else ""),
                flush=True,
            )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    meta = dict(jax=jax.__version__, backend=jax.default_backend(), machine=platform.machine(),
                cpu_count=__import__("os").cpu_count())
    args.out.write_text(json.dumps(dict(meta=meta, rows=rows), indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
