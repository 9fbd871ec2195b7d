"""Sweep ``p_rand`` for one family: communication class and optimal / worst / random values per value of p_rand.

The base MDP is built once per seed; every value of ``p_rand`` comes from the jittable kernel transform in a single
``vmap``, and the reference values of the whole grid are one batched computation.

    python scripts/sweep_prand.py                       # RiverSwim continuous, 10 values of p_rand
    python scripts/sweep_prand.py --family DeepSea --setting episodic --param size=10 --seeds 0 1
"""

from __future__ import annotations

import argparse
import ast
import csv
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import jaxmdp


def parse_params(items: list[str]) -> dict:
    out = {}
    for item in items:
        key, _, value = item.partition("=")
        try:
            out[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            out[key] = value
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--family", default="RiverSwim", choices=jaxmdp.families())
    parser.add_argument("--setting", default="continuous", choices=["continuous", "episodic"])
    parser.add_argument("--values", type=float, nargs="+", default=list(np.round(np.linspace(0.0, 0.9, 10), 4)))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--param", action="append", default=["size=10", "randomize_actions=False"],
                        help="family parameter key=value (repeatable)")
    parser.add_argument("--out", type=Path, default=Path("results/sweep_prand"))
    args = parser.parse_args()

    params = parse_params(args.param)
    args.out.mkdir(parents=True, exist_ok=True)
    grid = jnp.asarray(args.values, jnp.float32)

    @jax.jit
    def sweep(base):
        mdps = jax.vmap(jaxmdp.apply_p_rand, in_axes=(None, 0))(base, grid)
        return mdps, jax.vmap(jaxmdp.reference_values)(mdps)

    rows = []
    t0 = time.perf_counter()
    for seed in args.seeds:
        base = jaxmdp.make(args.family, episodic=args.setting == "episodic", seed=seed, **params)
        mdps, values = sweep(base.strip())
        classes = jaxmdp.communication_class(mdps)
        for i, p in enumerate(args.values):
            rows.append(
                dict(family=args.family, setting=args.setting, seed=seed, p_rand=p, n_states=base.n_states,
                     communication_class=classes[i].name, optimal_value=float(values.optimal[i]),
                     worst_value=float(values.worst[i]), random_value=float(values.random[i]))
            )
        print(f"seed {seed}: {len(args.values)} MDPs of {base.n_states} states in {time.perf_counter() - t0:.1f} s")
    path = args.out / f"{args.family}_{args.setting}_prand.csv"
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
