"""PSRL continuous: the structured extended-MDP plan against a baseline module (e.g. main's dense-candidate plan),
in one process, interleaved (docs/benchmarks/continuous_planning.md, "Structured plans").

For the largest MDP of each size bucket of "continuous ergodic" (as scripts/profile_continuous_plans.py: tuned
hyperparameters, ``max_psi = psi``), the agent's state after ``--play`` uniformly random steps, a cold plan and
``--more`` further steps; then one warm planning round of ``slots`` members under ``vmap`` (the runner's compacted
planning round of that bucket, ``default_plan_slots`` of a 70-member shard, or ``--slots``), timed for each module,
best of ``--repeats``, the modules alternating. Optional rows: ``--eta-pairs n`` also times the round after setting
``n`` random pairs to ``eta`` visits (posterior draws needed), and ``--memory`` reports XLA's memory analysis of one
``vmap`` over ``--memory-members`` members of the largest bucket (compiled, not run).

    python scripts/bench_psrl_structured_plan.py --baseline /work/main/agents/psrl_continuous.py --memory
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import agents.psrl_continuous as pc
from agents import estimated_model as em
from hardness.benchmark import sets
from jaxmdp.experiment.planning import default_plan_slots

from baseline_module import load_file  # scripts/ is on the path of a script run as python scripts/NAME.py
from bench_doc import interleaved_best
from profile_continuous_plans import bucket_labels, played


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--baseline", required=True, help="path of the baseline agents/psrl_continuous.py")
    p.add_argument("--set", default="continuous ergodic")
    p.add_argument("--labels", nargs="+", default=None, help="MDP labels (default: each bucket's largest)")
    p.add_argument("--slots", nargs="+", type=int, default=None, help="members per round, per label")
    p.add_argument("--play", type=int, default=5000)
    p.add_argument("--more", type=int, default=200)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--eta-pairs", type=int, default=0, help="also time with this many pairs at eta (0: not)")
    p.add_argument("--memory", action="store_true", help="XLA memory analysis of the largest bucket's batch")
    p.add_argument("--memory-members", type=int, default=20)
    p.add_argument("--out", default=None, help="write the rows as JSON here")
    return p


def stacked(state, n: int):
    return jax.tree.map(lambda y: jnp.broadcast_to(y[None], (n,) + y.shape), state)


def at_eta(state, n: int, seed: int = 0):
    """``state`` with ``n`` random real pairs given ``ceil(eta)`` more visits (to a random real next state)."""
    rng = np.random.default_rng(seed)
    S, A = state.Q.shape
    real = np.flatnonzero(np.asarray(state.state_mask)[:, None] & np.asarray(state.action_mask)[None, :])
    pairs = rng.choice(real, n, replace=False)
    s, a = pairs // A, pairs % A
    t = rng.choice(np.flatnonzero(np.asarray(state.state_mask)), n)
    add = int(np.ceil(float(state.constants.eta)))
    counts = state.counts.at[s, a, t].add(add)
    return state.replace(successors=em.with_dense_counts(state.successors, counts),
                         schedule=state.schedule.replace(visits=counts.sum(-1)))


def main(argv=None) -> list[dict]:
    args = build_parser().parse_args(argv)
    base = load_file(args.baseline, "psrl_continuous_baseline")
    labels = args.labels or bucket_labels(args.set)
    plans = {"baseline": jax.jit(jax.vmap(base.PSRL_CONTINUOUS.plan)), "structured": jax.jit(jax.vmap(pc.plan))}
    rows = []
    for i, label in enumerate(labels):
        mdp = sets.instance(args.set, label).build(0)
        S, A = int(np.sum(np.asarray(mdp.state_mask))), int(np.sum(np.asarray(mdp.action_mask)))
        hp = pc.PSRL_CONTINUOUS.default_hparams
        hp = hp.replace(max_psi=pc.psi(hp, S, A))
        state = jax.jit(lambda k: played(pc.PSRL_CONTINUOUS, mdp, hp, args.play, k))(jax.random.key(0))
        first = jax.tree.map(lambda y: y[0], plans["structured"](jax.random.split(jax.random.key(1), 1),
                                                                 stacked(state, 1)))
        state = jax.jit(lambda k, st: played(pc.PSRL_CONTINUOUS, mdp, hp, args.more, k, st))(jax.random.key(2), first)
        slots = args.slots[i] if args.slots else default_plan_slots(70)
        variants = [("random play", state)]
        if args.eta_pairs:
            variants.append((f"{args.eta_pairs} pairs at eta", at_eta(state, args.eta_pairs)))
        for what, st in variants:
            keys = jax.random.split(jax.random.key(3), slots)
            best = interleaved_best(plans, (keys, stacked(st, slots)), args.repeats)
            out = {name: plans[name](keys, stacked(st, slots)) for name in plans}
            row = dict(mdp=label, S=S, A=A, psi=int(st.constants.psi), eta=float(st.constants.eta),
                       pairs_at_eta=int(jnp.sum(st.schedule.visits >= st.constants.eta)), state=what, slots=slots,
                       baseline_s=best["baseline"], structured_s=best["structured"],
                       ratio=best["baseline"] / best["structured"],
                       iterations=[int(out[n].plan_iterations[0]) for n in plans])
            print(json.dumps(row), flush=True)
            rows.append(row)
        if args.memory and i == len(labels) - 1:
            n = args.memory_members
            keys = jax.random.split(jax.random.key(3), n)
            for name, module in (("baseline", base), ("structured", pc)):
                mem = jax.jit(jax.vmap(module.PSRL_CONTINUOUS.plan)).lower(keys, stacked(state, n)).compile()
                m = mem.memory_analysis()
                row = dict(mdp=label, S=S, members=n, module=name, temp_bytes=m.temp_size_in_bytes,
                           argument_bytes=m.argument_size_in_bytes, output_bytes=m.output_size_in_bytes)
                print(json.dumps(row), flush=True)
                rows.append(row)
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1) + "\n")
    return rows


if __name__ == "__main__":
    main()
    sys.exit(0)
