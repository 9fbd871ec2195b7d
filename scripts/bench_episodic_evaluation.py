"""Benchmark: the episodic indicator's policy evaluation, the whole backward pass (every step's ``V``, then ``V_0``
taken) against ``V_0`` alone (:func:`jaxmdp.dynamic_programming.finite_horizon_deterministic_start_values`, the same
numbers), as the runner calls it at a log: ``vmap`` over ``--members`` greedy policies of one MDP, one device.
``--stack``: the same on a stack of two MDPs, each member reading its own packed rows or the stack's
(:func:`jaxmdp.dynamic_programming.successor_rows`).

With ``--runner`` it also times episodic Q-learning in the lockstep runner (1 024 seeds, 4 000 steps, indicators
every 100 steps, 2 host devices) with either evaluation, in one process, interleaved, best of ``--runner-repeats`` (``--log-period 10`` makes the
logs ten times as frequent, so that their cost stands out of the run-to-run spread): the
benchmark replaces ``jaxmdp.experiment.runner.policy_values`` for the "whole pass" runs and puts it back after.

    python scripts/bench_episodic_evaluation.py --runner
    python scripts/bench_episodic_evaluation.py --stack
    python scripts/bench_episodic_evaluation.py --runner --log-period 10 --runner-repeats 3

Writes a section to ``docs/benchmarks/bench_episodic_evaluation.md`` (with the command) unless ``--doc ''``.
"""

from __future__ import annotations

import argparse
import functools
import os
from pathlib import Path

# The runner shards members over one host device per core (as scripts/bench_agents.py); set before jax is imported.
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import agents  # noqa: E402
import jaxmdp  # noqa: E402
from bench_agents import BENCH_MDPS  # noqa: E402
from bench_doc import append_section, best_seconds  # noqa: E402
from jaxmdp import dynamic_programming as dp  # noqa: E402
from jaxmdp.experiment.members import member_mdp  # noqa: E402
from jaxmdp.experiment import indicators, runner  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FAMILIES = ("RiverSwim", "Taxi", "MiniGridEmpty")


def whole_pass(mdp: jaxmdp.MDP, actions: jax.Array) -> jax.Array:
    """``V_0`` taken from the whole backward pass (the evaluation before ``V_0`` alone)."""
    return dp.finite_horizon_deterministic_evaluation(mdp, actions)[0]


def evaluation_rows(members: int, repeats: int) -> list[str]:
    rows = ["| MDP | S, A, H, K | whole pass, ms | V_0 alone, ms | ratio | same values |", "|---|---|---|---|---|---|"]
    for family in FAMILIES:
        mdp = jaxmdp.make(family, episodic=True, seed=0, **BENCH_MDPS[(family, True)]).strip()
        actions = jax.random.randint(jax.random.key(0), (members, mdp.H, mdp.n_states), 0, mdp.n_actions)
        f_old = jax.jit(jax.vmap(lambda a: whole_pass(mdp, a)))
        f_new = jax.jit(jax.vmap(lambda a: dp.finite_horizon_deterministic_start_values(mdp, a)))
        same = bool(jnp.all(f_old(actions) == f_new(actions)))
        t_old, t_new = (best_seconds(lambda f=f: f(actions), repeats) for f in (f_old, f_new))
        shape = f"{mdp.n_states}, {mdp.n_actions}, {mdp.H}, {mdp.succ.shape[-1]}"
        rows.append(f"| {family} | {shape} | {1e3 * t_old:.2f} | {1e3 * t_new:.2f} | {t_new / t_old:.2f}x | {same} |")
        print(rows[-1], flush=True)
    return rows


def stack_rows(members: int, repeats: int) -> list[str]:
    """Two Taxi MDPs stacked (members alternate between them): each member's own packed rows against the rows read
    from the stack by (MDP, state, action), ``V_0`` alone both ways."""
    kw = BENCH_MDPS[("Taxi", True)]
    stack = jaxmdp.stack([jaxmdp.make("Taxi", episodic=True, seed=s, **kw) for s in (0, 1)]).strip()
    rows = dp.successor_rows(stack)
    member = functools.partial(member_mdp, stack)
    actions = jax.random.randint(jax.random.key(0), (members, stack.H, stack.n_states), 0, stack.n_actions)
    index = jnp.arange(members, dtype=jnp.int32) % 2
    own = jax.jit(jax.vmap(lambda i, a: dp.finite_horizon_deterministic_start_values(member(i), a)))
    shared = jax.jit(jax.vmap(lambda i, a: dp.finite_horizon_deterministic_start_values(member(i), a, rows, i)))
    same = bool(jnp.all(own(index, actions) == shared(index, actions)))
    t_own, t_shared = (best_seconds(lambda f=f: f(index, actions), repeats) for f in (own, shared))
    return [
        "| two Taxi MDPs stacked | each member's own rows, ms | rows from the stack, ms | ratio | same values |",
        "|---|---|---|---|---|",
        f"| {members} members | {1e3 * t_own:.2f} | {1e3 * t_shared:.2f} | {t_shared / t_own:.2f}x | {same} |",
    ]


def runner_rows(repeats: int, log_period: int, seeds: int = 1024, steps: int = 4000) -> list[str]:
    agent = agents.get("q_learning_episodic")
    new = runner.policy_values

    def old(mdp, policy, iterative_sweeps=0, rows=None, member=None):  # grids of one MDP: rows is None
        if mdp.episodic and jnp.issubdtype(policy.dtype, jnp.integer):
            return whole_pass(mdp, policy)
        return indicators.policy_values(mdp, policy, iterative_sweeps)

    rows = ["| MDP | whole pass | V_0 alone | time ratio | same records |", "|---|---|---|---|---|"]
    try:
        for family in FAMILIES:
            mdp = jaxmdp.make(family, episodic=True, seed=0, **BENCH_MDPS[(family, True)])
            grid = runner.product([mdp], [agent.default_hparams], seeds=range(seeds))
            best, records = {}, {}
            for _ in range(repeats):
                for tag, fn in (("old", old), ("new", new)):
                    runner.policy_values = fn
                    runner._chunk_program.cache_clear()  # the chunk program calls policy_values when traced
                    runner.run(agent, grid, steps, log_period=log_period, n_records=10)  # compiles
                    res = runner.run(agent, grid, steps, log_period=log_period, n_records=10)
                    best[tag] = min(best.get(tag, np.inf), res.run_s)
                    records[tag] = res.column("normalized_cumulative_regret")
            rate = {k: f"{seeds * steps / v / 1e6:.2f} M agent-steps/s" for k, v in best.items()}
            same = bool(np.array_equal(records["old"], records["new"]))
            rows.append(f"| {family} | {rate['old']} | {rate['new']} | {best['new'] / best['old']:.2f}x | {same} |")
            print(rows[-1], flush=True)
    finally:
        runner.policy_values = new
        runner._chunk_program.cache_clear()
    return rows


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--members", type=int, default=512, help="policies evaluated at once (a shard of 1 024 seeds)")
    p.add_argument("--repeats", type=int, default=10, help="timed calls per evaluation (best is reported)")
    p.add_argument("--runner", action="store_true", help="also time episodic Q-learning in the runner")
    p.add_argument("--stack", action="store_true", help="also time the evaluation on a stack of two MDPs")
    p.add_argument("--runner-repeats", type=int, default=6, help="interleaved timed runs per evaluation")
    p.add_argument("--log-period", type=int, default=100, help="the runner's log period (10 magnifies the logs)")
    p.add_argument("--doc", default=str(ROOT / "docs" / "benchmarks" / "bench_episodic_evaluation.md"))
    args = p.parse_args(argv)
    body = [f"The evaluation at a log, {args.members} greedy policies vmapped on one device, best of {args.repeats}:", ""]
    body += evaluation_rows(args.members, args.repeats)
    if args.stack:
        body += ["", "A grid of several MDPs (the benchmark's size buckets):", ""] + stack_rows(args.members, args.repeats)
        print("\n".join(body[-3:]), flush=True)
    if args.runner:
        body += ["", f"Episodic Q-learning in the runner, indicators every {args.log_period} steps, best of "
                 f"{args.runner_repeats} interleaved runs:", ""]
        body += runner_rows(args.runner_repeats, args.log_period)
    if args.doc:
        append_section(args.doc, "The episodic indicator's evaluation: the whole backward pass against V_0 alone",
                       argv, body)


if __name__ == "__main__":
    main()
