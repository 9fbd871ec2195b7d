"""How many plans an epoch agent (UCRL2, PSRL continuous) makes over a run, measured, against the epoch bound
(paper §3.3; issue "benchmark"; docs/benchmarks/continuous_planning.md, "Plans counted").

``scripts/continuous_plan_wall_time.py`` charges every member the bound ``1 + S A log2(2 T / (S A))`` plans over
``T`` steps (its module docstring), which assumes every pair is visited about equally. An agent's visits are not
even: once it has found a good policy it plays a few pairs, whose epochs double, and no longer visits the rest. So
this script runs the agent, unchanged, on each named benchmark MDP (one runner call per MDP, ``--seeds`` members, the
benchmark's hyperparameters, planning as the runner does it) and counts the plans each member made: the runner's
initial plan and every plan it made because ``needs_plan`` said so (:func:`counting_plans`). Logs every
``--log-period`` steps only (they do not change what the agent does). Beside the count: the pairs each member visited
(each first visit ends an epoch, so at least that many plans) and ``visits_bound = 1 + sum over visited pairs of
(1 + log2 N(s, a))`` (a pair that ends ``j`` epochs has at least doubled its visits each time: ``j <= 1 + log2 N``),
the bound with the member's own visits.

Results go to ``--out`` (JSON, one entry per agent, set and MDP, written after each), which the wall-time script reads
with ``--plan-counts``; an entry already there is not measured again.

    python scripts/count_plans.py --out results/plan_counts.json --agents ucrl2 psrl_continuous --min-states 400
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any

import jax.numpy as jnp
import numpy as np

import agents as agent_registry
from hardness.benchmark import hparams as benchmark_hparams
from hardness.benchmark import sets
from jaxmdp.experiment import runner
from jaxmdp.experiment.agent_interface import Agent

sys.path.insert(0, str(Path(__file__).resolve().parent))
from continuous_plan_wall_time import plan_count_key, plans_bound  # noqa: E402


def counting_plans(agent: Agent) -> Agent:
    """``agent`` with state ``(state, plans)``: the same actions, updates, plans and policies, and ``plans`` (``int32``)
    the number of times ``plan`` ran on the member's state and was kept. The runner keeps a plan only for the members
    that were due (or, before the first action, all), so ``plans`` counts exactly the plans of a run."""

    def on_inner(f):
        return None if f is None else (lambda state, *args: f(state[0], *args))

    return dataclasses.replace(
        agent,
        init=lambda key, spec, hp: (agent.init(key, spec, hp), jnp.zeros((), jnp.int32)),
        act=lambda key, state, obs, h: agent.act(key, state[0], obs, h),
        update=lambda state, transition: (agent.update(state[0], transition), state[1]),
        plan=lambda key, state: (agent.plan(key, state[0]), state[1] + 1),
        policy=on_inner(agent.policy),
        needs_plan=on_inner(agent.needs_plan),
        greedy_actions=on_inner(agent.greedy_actions),
        warm_policy=on_inner(agent.warm_policy),
        policy_start=on_inner(agent.policy_start),
        diagnostics=on_inner(agent.diagnostics),
    )


def count(agent_name: str, set_name: str, label: str, n_steps: int, seeds: int, log_period: int) -> dict[str, Any]:
    """Plans per member of ``agent_name`` (benchmark hyperparameters, ``"tuned"``) over ``n_steps`` steps on the
    benchmark MDP ``label`` of ``set_name``, seeds ``0 .. seeds - 1``, with the bound and the run's seconds."""
    inst = sets.instance(set_name, label)
    mdp = inst.build(0)
    hp = benchmark_hparams.fit_static_sizes(agent_name, [benchmark_hparams.hparams_for(agent_name)], [mdp])[0]
    grid = runner.product([mdp], [hp], range(seeds))
    result = runner.run(counting_plans(agent_registry.get(agent_name)), grid, n_steps, log_period=log_period,
                        n_records=1)
    S, A = int(np.sum(mdp.state_mask)), int(np.sum(mdp.action_mask))
    visits = np.asarray(result.agent_state[0].schedule.visits, np.float64)  # [seeds, S, A]
    seen = visits > 0  # an unvisited pair adds 0 to visits_bound: log2(max(0, 1)) = 0
    return dict(agent=agent_name, set=set_name, mdp=label, states=S, actions=A, steps=n_steps, seeds=seeds,
                plans=np.asarray(result.agent_state[1]).tolist(), bound=plans_bound(S, A, n_steps),
                pairs_visited=seen.sum(axis=(1, 2)).tolist(),
                visits_bound=(1 + (seen + np.log2(np.maximum(visits, 1))).sum(axis=(1, 2))).tolist(),
                run_s=result.run_s, compile_s=result.compile_s)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="JSON results file (resumed if it exists)")
    p.add_argument("--agents", nargs="+", default=["ucrl2", "psrl_continuous"], choices=["ucrl2", "psrl_continuous"])
    p.add_argument("--sets", nargs="+", default=["continuous ergodic", "continuous communicating"])
    p.add_argument("--labels", nargs="+", default=None, help="MDP labels, e.g. MiniGridRooms/prms_1 (default: all)")
    p.add_argument("--min-states", type=int, default=0, help="only MDPs with at least this many states")
    p.add_argument("--steps", type=int, default=500_000)
    p.add_argument("--seeds", type=int, default=1)
    p.add_argument("--log-period", type=int, default=50_000)
    args = p.parse_args(argv)
    continuous = [s for s in sets.SETTINGS if not sets.is_episodic(s)]
    for set_name in args.sets:
        if set_name not in continuous:
            raise ValueError(f"--sets must name continuous settings {continuous}; got {set_name!r}")
    known = {i.label for set_name in args.sets for i in sets.instances(set_name)}
    unknown = sorted(set(args.labels or ()) - known)
    if unknown:
        raise ValueError(f"--labels {unknown} are not MDPs of {args.sets}; they have {sorted(known)}")
    results = json.loads(args.out.read_text()) if args.out.exists() else {}
    todo = []
    for set_name in args.sets:
        for inst in sets.instances(set_name):
            if args.labels is not None and inst.label not in args.labels:
                continue
            if int(np.sum(inst.build(0).state_mask)) < args.min_states:
                continue
            todo += [(a, set_name, inst.label) for a in args.agents
                     if plan_count_key(a, set_name, inst.label) not in results]
    for k, (agent_name, set_name, label) in enumerate(todo):
        started = time.perf_counter()
        entry = count(agent_name, set_name, label, args.steps, args.seeds, args.log_period)
        results[plan_count_key(agent_name, set_name, label)] = entry
        tmp = args.out.with_name(args.out.name + ".tmp")
        tmp.write_text(json.dumps(results, indent=1) + "\n")
        tmp.replace(args.out)
        print(f"[{k + 1}/{len(todo)}] {agent_name} on {set_name} {label} ({entry['states']} x {entry['actions']}): "
              f"plans {entry['plans']} against the bound {entry['bound']:.0f}, {time.perf_counter() - started:.0f} s",
              file=sys.stderr, flush=True)
    return results


if __name__ == "__main__":
    main()
