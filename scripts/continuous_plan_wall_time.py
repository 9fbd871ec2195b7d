"""Wall time of the continuous settings' epoch agents (PSRL continuous, UCRL2) at 500 000 steps: steps and plans
measured apart and extrapolated (paper §3.3; issue "Performance"; docs/benchmarks/continuous_planning.md).

A few hundred steps of these agents are no sample of a long run: early on nearly every step ends an epoch (a pair's
first visits), later epochs are rare. So the run time of a batch (one agent on one size bucket of the full plan,
:func:`hardness.benchmark.run.plan`) is split into

* **steps**: the bucket's real batch (all its members and seeds, indicators every 100 steps) with planning switched
  off (the agent's ``needs_plan`` always False), through ``run_benchmark``, for each of the two ``--steps`` counts:
  ``c_step`` = the difference of their run seconds per member-step (both shards, as the benchmark runs them;
  :func:`benchmark_wall_time.rate_and_fixed`). Both counts must cut their runs into as many runner chunks as the
  full run (``N1 >= 2000``): a chunk ends with a checkpoint of the batch (about 0.3-0.5 s at 948 states, 20
  members), which a short run of many chunks would otherwise charge to its steps, 5x the true rate at 948 states;
* **plans**: one round of the runner's compacted planning, ``slots = default_plan_slots(members per shard)`` members
  planned under ``vmap`` (:mod:`jaxmdp.experiment.planning`), on the bucket's largest MDP padded to the bucket's
  shapes, after ``--play`` uniformly random steps, a cold plan and ``--more`` further steps (so the timed plan is
  warm-started from the previous epoch's values, as in a run): ``c_round`` seconds a round inside one compiled
  program, as the runner pays it (:func:`profile_continuous_plans.in_program_seconds`; a round called as a program
  of its own, ``c_round_call``, costs more on a CPU and is recorded beside it), best of ``--repeats``;
* **plan count**: per member at most ``1 + S A log2(2 T / (S A))`` plans over ``T`` steps (``S``, ``A`` the member's
  real states and actions). Why: both agents re-plan when the pair just played has as many visits in the epoch as
  before it (:mod:`agents.epochs`); a pair that ends ``j`` epochs has at least doubled its count each time from 1,
  so ``j <= 1 + log2 N(s, a)``, and ``sum_(s,a) (1 + log2 N(s, a)) <= S A (1 + log2(T / (S A)))`` by concavity
  (``sum N = T``); the ``1`` is the initial plan. (Jaksch et al. 2010, Prop. 18, bound the same count by the looser
  ``S A log2(8 T / (S A))``.) An upper bound: unreachable pairs and uneven visits give fewer plans. With
  ``--plan-counts FILE`` (written by ``scripts/count_plans.py``) a member of an MDP measured at ``T`` steps counts
  the mean plans measured there instead (:func:`member_plans`); the others keep the bound.

Extrapolated run seconds of a batch (:func:`extrapolate`): ``c_step * members * T + plans / shards * c_round / slots``
(every round full) and, at the other extreme, ``... + plans / shards * c_one`` (every round plans one member, which
:func:`~jaxmdp.experiment.planning.plan_due` plans alone: ``c_one`` is a round of one slot). Buckets of a set not
measured use the rates of the same agent's measured buckets, interpolated linearly in the largest state count (each
of ``c_step`` and ``c_round`` apart, so that two calls with the same ``--out`` can measure the plans of every bucket
and the steps of a few; a bucket's value already in ``measured.json`` is not measured again). ``c_step`` counts as 0
while no bucket of the agent has one.

    python scripts/continuous_plan_wall_time.py --out results/continuous_plans --skip-steps
    python scripts/continuous_plan_wall_time.py --out results/continuous_plans --skip-plans --buckets b0 b3 \
        --steps 2000 4000
"""

from __future__ import annotations

import os

if __name__ == "__main__" and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={os.cpu_count() or 1}"
    ).strip()

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import agents as agent_registry  # noqa: E402
import jaxmdp  # noqa: E402
from hardness.benchmark import hparams as benchmark_hparams  # noqa: E402
from hardness.benchmark import run, sets  # noqa: E402
from jaxmdp.experiment.planning import default_plan_slots  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import benchmark_wall_time as wall_time  # noqa: E402
from profile_continuous_plans import best_of, in_program_seconds, warm_state  # noqa: E402

T_FULL = 500_000
SEEDS = 20
AGENTS = ("psrl_continuous", "ucrl2")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sets", nargs="+", default=["continuous ergodic"], help="continuous sets to measure")
    p.add_argument("--agents", nargs="+", default=list(AGENTS))
    p.add_argument("--buckets", nargs="+", default=None, help="bucket ids to measure, e.g. b0 b3 (default: all)")
    p.add_argument("--steps", type=int, nargs=2, default=[2000, 4000], metavar=("N1", "N2"),
                   help="steps of the two no-planning runs (%(default)s; each cut into the full run's chunk count)")
    p.add_argument("--play", type=int, default=5000, help="random steps before the timed plan (%(default)s)")
    p.add_argument("--more", type=int, default=200, help="random steps between the cold and the timed plan")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--skip-steps", action="store_true", help="do not run the no-planning batches (measure plans)")
    p.add_argument("--skip-plans", action="store_true", help="do not time planning rounds (measure steps)")
    p.add_argument("--plan-counts", type=Path, default=None,
                   help="plans measured by scripts/count_plans.py, used instead of the bound where present")
    p.add_argument("--out", type=Path, required=True)
    return p


def plans_bound(S: int, A: int, T: int = T_FULL) -> float:
    """``1 + min(T, V log2(2 T / V))`` with ``V = min(S A, T)`` pairs that can be visited (module docstring; the
    minimum with ``T``: at most one re-plan per step)."""
    V = min(S * A, T)
    return float(1 + min(T, V * math.log2(2.0 * T / V)))


def plan_count_key(agent: str, set_name: str, label: str) -> str:
    """The key of one MDP's measurement in ``scripts/count_plans.py``'s file."""
    return f"{agent} | {set_name} | {label}"


def member_plans(agent: str, set_name: str, label: str, S: int, A: int, counts: dict | None,
                 T: int = T_FULL) -> tuple[float, bool]:
    """Plans of one member of ``agent`` on MDP ``label`` of ``set_name`` (``S`` states, ``A`` actions) over ``T``
    steps, and whether measured: the mean over the seeds of ``counts`` (``scripts/count_plans.py``'s file) if it
    holds that MDP at ``T`` steps, else :func:`plans_bound`."""
    entry = (counts or {}).get(plan_count_key(agent, set_name, label))
    if entry is not None and entry["steps"] == T:
        return float(np.mean(entry["plans"])), True
    return plans_bound(S, A, T), False


def no_planning(agent):
    """``agent`` that never asks for a plan (``needs_plan`` always False): its steps and logs alone."""
    return dataclasses.replace(agent, needs_plan=lambda state: jnp.zeros((), bool))


def step_cost(set_name: str, agent: str, labels: list[str], steps: Sequence[int], out: Path) -> dict:
    """Run seconds per member-step of the bucket's batch with planning switched off, from runs of ``steps = (N1,
    N2)`` steps (module docstring)."""
    saved = agent_registry.AGENTS[agent]
    agent_registry.AGENTS[agent] = no_planning(saved)
    try:
        m1, m2 = [wall_time.measure(set_name, agent, labels, SEEDS, n, out / f"steps_{n}") for n in steps]
    finally:
        agent_registry.AGENTS[agent] = saved
    c_step, fixed = wall_time.rate_and_fixed(dict(m1, steps2=m2["steps"], run2_s=m2["run_s"]))
    return dict(step_members=m1["members"], step_steps=list(steps), step_run_s=[m1["run_s"], m2["run_s"]],
                step_compile_s=m1["compile_s"], c_step=c_step, step_fixed_s=fixed)


def round_cost(set_name: str, agent_name: str, labels: list[str], slots: int, play: int, more: int,
               repeats: int) -> dict:
    """Seconds of one planning round of ``slots`` members on the bucket's largest MDP, padded to the bucket
    (``c_round``), and of a round of one member (``c_one``)."""
    insts = {i.label: i for i in sets.instances(set_name)}
    mdps = [insts[label].build(0) for label in labels]
    agent = agent_registry.get(agent_name)
    hp = benchmark_hparams.fit_static_sizes(agent_name, [agent.default_hparams], mdps)[0]
    largest = max(range(len(mdps)), key=lambda i: int(np.sum(np.asarray(mdps[i].state_mask))))
    mdp = jax.tree.map(lambda x: x[largest], jaxmdp.stack(mdps))
    state = warm_state(agent, mdp, hp, play, more)
    keys = jax.random.split(jax.random.key(1), slots)
    plan = jax.jit(jax.vmap(agent.plan))
    again = jax.tree.map(lambda y: jnp.broadcast_to(y[None], (slots,) + y.shape), state)

    def timed(n):  # (per call, inside one program) for a round of n slots
        k, st = keys[:n], jax.tree.map(lambda y: y[:n], again)
        return best_of(plan, k, st, repeats=repeats)[0], in_program_seconds(plan, k, st, repeats=repeats)

    call, c_round = timed(slots)
    one_call, c_one = timed(1) if slots > 1 else (call, c_round)
    return dict(plan_mdp=labels[largest], slots=slots, c_round=c_round, c_one=c_one, c_round_call=call,
                c_one_call=one_call)


def extrapolate(rows: list[dict], T: int = T_FULL) -> dict:
    """The batches' run seconds at ``T`` steps from their measured costs (module docstring), in place on ``rows``.

    Each row holds ``agent``, ``members``, ``shards``, ``slots``, ``max_states``, ``plans`` (the members' plan
    counts: counted where measured, else the bound) and, where measured, ``c_round``, ``c_one`` and ``c_step``. A cost
    missing from a row is interpolated linearly in ``max_states`` between the same agent's measured rows (clipped at
    the ends; ``c_round`` per slot, since buckets differ in their slots) and flagged ``<cost>_interpolated``. A row
    with ``c_round`` and ``c_one`` gets ``steps_s = c_step members T`` (``c_step`` 0 if none), ``plans_s_packed =
    plans / shards c_round / slots``, ``plans_s_one_per_round = plans / shards c_one``, ``run_s_low`` and
    ``run_s_high`` (steps plus each); a row without them (e.g. a ``measured.json`` written before ``c_one``) is left
    out of the totals. Returns ``{"T", "seeds", "rows", "run_s_low", "run_s_high"}``; the totals sum the rows done.
    """
    per_slot = lambda r: r["c_round"] / r["slots"]  # noqa: E731
    for key, rate in (("c_round", per_slot), ("c_one", lambda r: r["c_one"]), ("c_step", lambda r: r["c_step"])):
        for row in rows:
            same = sorted((r for r in rows if key in r and not r.get(f"{key}_interpolated")
                           and r["agent"] == row["agent"]), key=lambda r: r["max_states"])
            if key not in row and same:
                value = float(np.interp(row["max_states"], [r["max_states"] for r in same], [rate(r) for r in same]))
                row[key] = value * row["slots"] if key == "c_round" else value
                row[f"{key}_interpolated"] = True
    for row in rows:
        if "c_round" not in row or "c_one" not in row:
            continue
        steps_s = row.get("c_step", 0.0) * row["members"] * T
        per_shard = row["plans"] / row["shards"]
        row.update(steps_s=steps_s, plans_s_packed=per_shard * row["c_round"] / row["slots"],
                   plans_s_one_per_round=per_shard * row["c_one"])
        row.update(run_s_low=steps_s + row["plans_s_packed"], run_s_high=steps_s + row["plans_s_one_per_round"])
    done = [r for r in rows if "run_s_low" in r]
    return dict(T=T, seeds=SEEDS, rows=rows, run_s_low=sum(r["run_s_low"] for r in done),
                run_s_high=sum(r["run_s_high"] for r in done))


def main(argv: list[str] | None = None) -> dict:
    parser = build_parser()
    args = parser.parse_args(argv)
    full_chunks = wall_time.n_chunks(T_FULL)
    if not args.skip_steps and (args.steps[0] >= args.steps[1]
                                or [wall_time.n_chunks(n) for n in args.steps] != [full_chunks] * 2):
        parser.error(f"--steps {args.steps[0]} {args.steps[1]}: take N1 < N2 whose runs are cut into the full run's "
                     f"{full_chunks} runner chunks (N1 >= 2000), so that no checkpoint is charged to the steps")
    args.out.mkdir(parents=True, exist_ok=True)
    full = run.RunConfig(sets=tuple(s for s in sets.SETTINGS if not sets.is_episodic(s)), hparams="reference",
                         seeds=tuple(range(SEEDS)), n_steps=T_FULL, log_period=100, n_buckets=4)
    _, batches = run.plan(full)
    shards = max(d for d in range(1, jax.local_device_count() + 1) if all(len(b.members) % d == 0 for b in batches))
    state_path = args.out / "measured.json"
    measured = json.loads(state_path.read_text()) if state_path.exists() else {}
    counts = json.loads(args.plan_counts.read_text()) if args.plan_counts is not None else None
    rows = []
    for b in batches:
        if b.agent not in args.agents:
            continue
        insts = {i.label: i for i in sets.instances(b.set_name)}
        labels = sorted({m for m, _ in b.members})
        shapes = {lab: insts[lab].build(0) for lab in labels}
        real = {lab: (int(np.sum(np.asarray(m.state_mask))), int(np.sum(np.asarray(m.action_mask))))
                for lab, m in shapes.items()}
        bucket = b.id.split(".")[-1]
        plans = [member_plans(b.agent, b.set_name, m, *real[m], counts) for m, _ in b.members]
        row = dict(batch=b.id, set=b.set_name, agent=b.agent, bucket=bucket, members=len(b.members), shards=shards,
                   max_states=max(S for S, _ in real.values()), plans=sum(n for n, _ in plans),
                   plans_bound=sum(plans_bound(*real[m]) for m, _ in b.members),
                   members_counted=sum(known for _, known in plans))
        if b.set_name in args.sets and (args.buckets is None or bucket in args.buckets):
            m = measured.setdefault(b.id, {})
            if "c_round_call" not in m and not args.skip_plans:  # absent: not measured, or per call (before)
                slots = default_plan_slots(len(b.members) // shards)
                m.update(round_cost(b.set_name, b.agent, labels, slots, args.play, args.more, args.repeats))
            if "c_step" not in m and not args.skip_steps:
                m.update(step_cost(b.set_name, b.agent, labels, args.steps, args.out / b.id))
            state_path.write_text(json.dumps(measured, indent=1) + "\n")
            print(b.id, json.dumps(m), file=sys.stderr, flush=True)
        row.update(measured.get(b.id, {}), slots=default_plan_slots(len(b.members) // shards))
        rows.append(row)
    result = extrapolate(rows)
    for row in result["rows"]:
        if "run_s_low" in row:
            print(f"{row['batch']}: {row['members']} members ({row['members_counted']} with counted plans), "
                  f"S <= {row['max_states']}, plans {row['plans']:.3g} (bound {row['plans_bound']:.3g}), "
                  f"round of {row['slots']} {row['c_round'] * 1e3:.1f} ms, step {row.get('c_step', 0.0):.2e} s: "
                  f"{row['run_s_low'] / 3600:.1f} h (rounds full) / {row['run_s_high'] / 3600:.1f} h (one member a "
                  "round)", file=sys.stderr)
    done = [r for r in rows if "run_s_low" in r]
    (args.out / "continuous_plan_wall_time.json").write_text(json.dumps(result, indent=1) + "\n")
    print(f"continuous epoch agents, {len(done)} of {len(rows)} batches: {result['run_s_low'] / 3600:.1f} h (rounds "
          f"full) / {result['run_s_high'] / 3600:.1f} h (one member a round)", file=sys.stderr)
    return result


if __name__ == "__main__":
    main()
    sys.exit(0)
