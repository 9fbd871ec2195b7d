"""How early ``dp.successor_gain_bounds`` may give up (its ``give_up``), on the benchmark's continuous MDPs.

Survey: seed 0 of every MDP of both continuous settings; for each, five deterministic policies (the gain-optimal one,
that one with 5%, 20% and 50% of its states' actions redrawn, and a uniformly random one). The bounds run with the
runner's 128 sweeps, without giving up and with each ``--give-up`` factor; reported per factor: the sweeps in all, the
certificates kept and lost, and at how many sweeps the uncertified chains stopped. Where both certify, the bounds and
sweeps must be the same (checked). Timing: ``indicators.policy_values`` as the runner calls it (bounds, then the
banded exact solve where they fail) on ``--time-labels``, without and with the runner's factor, best of
``--repeats`` alternating calls in one process, on the 20%-redrawn policy.

    PYTHONPATH=$PWD python scripts/bench_gain_give_up.py --give-up 1 4 16
"""

from __future__ import annotations

import argparse
import collections
import time

import jax
import jax.numpy as jnp
import numpy as np

from hardness.benchmark import sets
from jaxmdp import dynamic_programming as dp
from jaxmdp import gth
from jaxmdp.experiment import indicators

SETS = ("continuous ergodic", "continuous communicating")


def policies(mdp, rng: np.random.Generator) -> list[jax.Array]:
    """The optimal policy, it with 5 / 20 / 50% of its actions redrawn, and a random one (action indices)."""
    S, A = mdp.n_states, mdp.n_actions
    best = np.asarray(jnp.argmax(dp.optimal_gain(mdp).policy, -1))  # the one-hot [S, A] policy's actions
    out = [best] + [np.where(rng.random(S) < f, rng.integers(0, A, S), best) for f in (0.05, 0.2, 0.5)]
    return [jnp.asarray(p, jnp.int32) for p in out + [rng.integers(0, A, S)]]


def survey(factors: list[float], sweeps: int) -> None:
    bounds = {g: jax.jit(lambda m, p, g=g: dp.successor_gain_bounds(m, p, max_sweeps=sweeps, give_up=g))
              for g in [None, *factors]}
    stats = {g: collections.Counter() for g in bounds}
    rng = np.random.default_rng(0)
    for name in SETS:
        for inst in sets.instances(name):
            mdp = inst.build(0).strip()
            for p in policies(mdp, rng):
                plain = bounds[None](mdp, p)
                for g, f in bounds.items():
                    b = plain if g is None else f(mdp, p)
                    ok, n = bool(b.certified), int(b.sweeps)
                    stats[g]["sweeps"] += n
                    stats[g]["certified" if ok else f"stopped at {n}"] += 1
                    if ok and bool(plain.certified):
                        assert n == int(plain.sweeps) and np.array_equal(b.lower, plain.lower), (inst.label, g)
                    stats[g]["lost"] += bool(plain.certified) and not ok
    stops = sorted({k for s in stats.values() for k in s if k.startswith("stopped")}, key=lambda k: int(k.split()[-1]))
    print("| give_up | sweeps in all | certified | lost | " + " | ".join(stops) + " |")
    print("|---" * (4 + len(stops)) + "|")
    for g, s in stats.items():
        print(f"| {g} | {s['sweeps']} | {s['certified']} | {s['lost']} | " + " | ".join(str(s[k]) for k in stops)
              + " |")


def timing(labels: list[str], repeats: int, sweeps: int) -> None:
    instances = {f"{name}/{inst.label}": inst for name in SETS for inst in sets.instances(name)}
    print("\n| MDP | S | without | with give_up |\n|---|---|---|---|")
    for label in labels:
        mdp = instances[label].build(0).strip()
        order, width = gth.band_order(mdp)
        pi = policies(mdp, np.random.default_rng(0))[2]
        band = dict(order=jnp.asarray(order), bandwidth=width, check_band=False)
        values = {g: jax.jit(lambda p, g=g: indicators.policy_values(mdp, p, sweeps, give_up=g, **band))
                  for g in (None, indicators.ITERATIVE_GAIN_GIVE_UP)}
        fns = {g: f.lower(pi).compile() for g, f in values.items()}
        best = {g: np.inf for g in fns}
        for _ in range(repeats):
            for g, f in fns.items():
                t = time.perf_counter()
                jax.block_until_ready(f(pi))
                best[g] = min(best[g], time.perf_counter() - t)
        print(f"| {label} | {mdp.n_states} | " + " | ".join(f"{t * 1e3:.2f} ms" for t in best.values()) + " |")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--give-up", type=float, nargs="+", default=[indicators.ITERATIVE_GAIN_GIVE_UP])
    p.add_argument("--sweeps", type=int, default=indicators.ITERATIVE_GAIN_SWEEPS, help="(%(default)s)")
    p.add_argument("--time-labels", nargs="*", default=[
        "continuous ergodic/MiniGridRooms/prms_1", "continuous ergodic/MiniGridEmpty/prms_2",
        "continuous communicating/MiniGridRooms/prms_2"])
    p.add_argument("--repeats", type=int, default=30)
    args = p.parse_args(argv)
    survey(args.give_up, args.sweeps)
    timing(args.time_labels, args.repeats, args.sweeps)


if __name__ == "__main__":
    main()
