"""Benchmark: grids of several MDPs (what every batch of the benchmark is: a size bucket) against grids of one MDP.

1. The environment step alone, ``vmap`` over ``--members`` members laid out over ``n`` stacked episodic Taxi MDPs
   (seeds ``0 .. n-1``), 500 random-action steps in one jitted ``lax.scan``: ``env.step`` on each member's own MDP
   (taken out of the stack with ``tree.map(lambda x: x[i], ...)``) against ``env.step_member`` on the stack, and
   ``env.step`` on a single unbatched MDP as the floor; best of ``--repeats`` interleaved runs, one device.
2. The lockstep runner, episodic Q-learning and the random agent, ``--members`` members, 4 000 steps, indicators
   every 100 steps and none, on 1, 2 and 4 stacked Taxi MDPs (2 host devices).

    python scripts/bench_stacked_grid.py

Writes a section to ``docs/benchmarks/bench_stacked_grid.md`` (with the command) unless ``--doc ''``.
"""

from __future__ import annotations

import argparse
import functools
import os
import time
from pathlib import Path

# The runner shards members over one host device per core (as scripts/bench_agents.py); set before jax is imported.
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import agents  # noqa: E402
import jaxmdp  # noqa: E402
from bench_agents import BENCH_MDPS, NO_INDICATORS  # noqa: E402
from bench_doc import append_section  # noqa: E402
from jaxmdp import env  # noqa: E402
from jaxmdp.experiment.members import member_mdp  # noqa: E402
from jaxmdp.experiment import runner  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def taxis(n: int) -> list[jaxmdp.MDP]:
    return [jaxmdp.make("Taxi", episodic=True, seed=s, **BENCH_MDPS[("Taxi", True)]) for s in range(n)]


def step_rows(members: int, n_mdps: int, steps: int, repeats: int) -> list[str]:
    stack = jaxmdp.stack(taxis(n_mdps)).strip()
    single = jax.tree.map(lambda x: x[0], stack)
    index = jnp.arange(members, dtype=jnp.int32) % n_mdps
    member = functools.partial(member_mdp, stack)
    kinds = {
        "own MDP (env.step)": lambda k, s, a, i: env.step(k, s, a, member(i)),
        "stack (env.step_member)": lambda k, s, a, i: env.step_member(k, s, a, stack, i),
        "one MDP, no stack (env.step)": lambda k, s, a, i: env.step(k, s, a, single),
    }

    def program(step):
        @jax.jit
        def run(key):
            _, state = jax.vmap(lambda k, i: env.reset(k, member(i)))(jax.random.split(key, members), index)

            def body(state, k):
                k_act, k_step = jax.random.split(k)
                action = jax.random.randint(k_act, (members,), 0, stack.n_actions)
                _, state, reward, *_ = jax.vmap(step)(jax.random.split(k_step, members), state, action, index)
                return state, reward.sum()

            return jax.lax.scan(body, state, jax.random.split(jax.random.fold_in(key, 1), steps))[1].sum()

        return run

    programs = {name: program(step) for name, step in kinds.items()}
    results = {name: float(run(jax.random.key(0))) for name, run in programs.items()}
    best = {name: np.inf for name in programs}
    for _ in range(repeats):
        for name, run in programs.items():
            t = time.perf_counter()
            jax.block_until_ready(run(jax.random.key(0)))
            best[name] = min(best[name], time.perf_counter() - t)
    same = results["own MDP (env.step)"] == results["stack (env.step_member)"]
    rows = [f"| {name} | {members * steps / best[name] / 1e6:.2f} M steps/s |" for name in programs]
    return [f"{n_mdps} Taxi MDPs stacked, {members} members, {steps} steps (same rewards both ways: {same}):", "",
            "| step | rate |", "|---|---|", *rows, ""]


def runner_rows(members: int, repeats: int, steps: int = 4000) -> list[str]:
    rows = ["| agent | MDPs in the grid | indicators every 100 steps | no indicators |", "|---|---|---|---|"]
    for name in ("q_learning_episodic", "random_episodic"):
        agent = agents.get(name)
        for n_mdps in (1, 2, 4):
            grid = runner.product(taxis(n_mdps), [agent.default_hparams], seeds=range(members // n_mdps))
            rate = {}
            for lp in (100, NO_INDICATORS):
                runner.run(agent, grid, steps, log_period=lp, n_records=10)  # compiles
                best = min(runner.run(agent, grid, steps, log_period=lp, n_records=10).run_s for _ in range(repeats))
                rate[lp] = f"{grid.n_members * steps / best / 1e6:.2f} M agent-steps/s"
            rows.append(f"| {name} | {n_mdps} | {rate[100]} | {rate[NO_INDICATORS]} |")
            print(rows[-1], flush=True)
    return rows


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--members", type=int, default=1024)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--no-runner", action="store_true", help="only the environment step")
    p.add_argument("--doc", default=str(ROOT / "docs" / "benchmarks" / "bench_stacked_grid.md"))
    args = p.parse_args(argv)
    body = []
    for n_mdps in (2, 4):
        body += step_rows(args.members, n_mdps, 500, args.repeats)
        print("\n".join(body[-6:]), flush=True)
    if not args.no_runner:
        body += [f"The runner, {args.members} members (best of {args.repeats}):", ""] + runner_rows(
            args.members, args.repeats)
    if args.doc:
        append_section(args.doc, "Grids of several MDPs against grids of one", argv, body)


if __name__ == "__main__":
    main()
