"""Time ``dp.gain_vector`` (the runner's dense fallback for continuous indicators) on the benchmark's largest
continuous MDPs, against the same function at a git revision (default ``main``), in one process.

For each MDP (``hardness.benchmark`` "continuous ergodic", seed 0) and each policy (a random deterministic one,
the gain-optimal one from ``dp.optimal_gain``, and that one with a fraction of its states' actions redrawn at random,
as a partly learnt Q-learning policy would be), both versions are compiled once and then called in alternation,
``--repeats`` times each; the best time of each is reported, with the largest relative difference of the two gain
vectors. Under load the best-of times and their ratio are what to read (docs/benchmarks/continuous_indicators.md).

    PYTHONPATH=$PWD python scripts/bench_gain_vector.py --labels MiniGridEmpty/prms_2 MiniGridEmpty/prms_3 \\
        MiniGridRooms/prms_1 --repeats 5
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from hardness.benchmark import sets
from jaxmdp import dynamic_programming as dp

ROOT = Path(__file__).resolve().parents[1]


def baseline_module(revision: str):
    """``jaxmdp/dynamic_programming.py`` as it is at ``revision``, imported as a module of its own."""
    source = subprocess.run(["git", "show", f"{revision}:jaxmdp/dynamic_programming.py"], cwd=ROOT, check=True,
                            capture_output=True, text=True).stdout
    path = Path(tempfile.mkdtemp()) / "baseline_dynamic_programming.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("baseline_dynamic_programming", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def policies(mdp, rng: np.random.Generator, redrawn: float) -> dict[str, jax.Array]:
    S, A = mdp.n_states, mdp.n_actions
    best = np.asarray(jnp.argmax(dp.optimal_gain(mdp).policy, -1))
    partial = np.where(rng.random(S) < redrawn, rng.integers(0, A, S), best)
    out = dict(random=rng.integers(0, A, S), optimal=best, partly_learnt=partial)
    return {k: jax.nn.one_hot(jnp.asarray(v), A, dtype=mdp.R.dtype) for k, v in out.items()}


def best_times(fns: dict, args: tuple, repeats: int) -> dict[str, float]:
    times = {k: np.inf for k in fns}
    for _ in range(repeats):
        for k, f in fns.items():
            t = time.perf_counter()
            jax.block_until_ready(f(*args))
            times[k] = min(times[k], time.perf_counter() - t)
    return times


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--labels", nargs="+", default=["MiniGridEmpty/prms_2", "MiniGridEmpty/prms_3",
                                                   "MiniGridRooms/prms_1"], help="MDPs of the set (%(default)s)")
    p.add_argument("--set", default="continuous ergodic", help="benchmark set (%(default)s)")
    p.add_argument("--baseline", default="main", help="git revision timed against (%(default)s)")
    p.add_argument("--repeats", type=int, default=5, help="calls of each version per policy (%(default)s)")
    p.add_argument("--redrawn", type=float, default=0.2, help="fraction of redrawn actions (%(default)s)")
    args = p.parse_args(argv)
    base = baseline_module(args.baseline)
    fns = {args.baseline: jax.jit(base.gain_vector), "this tree": jax.jit(dp.gain_vector)}
    instances = {inst.label: inst for inst in sets.instances(args.set)}
    rng = np.random.default_rng(0)
    print(f"| MDP | S | policy | {args.baseline} s | this tree s | ratio | max rel. diff |")
    print("|---|---|---|---|---|---|---|")
    for label in args.labels:
        mdp = instances[label].build(0)
        for name, pi in policies(mdp, rng, args.redrawn).items():
            out = {k: np.asarray(f(mdp, pi)) for k, f in fns.items()}  # compiles
            times = best_times(fns, (mdp, pi), args.repeats)
            a, b = out[args.baseline], out["this tree"]
            diff = float(np.max(np.abs(a - b)) / np.max(np.abs(a)))
            t0, t1 = times[args.baseline], times["this tree"]
            print(f"| {label} | {mdp.n_states} | {name} | {t0:.4f} | {t1:.4f} | {t0 / t1:.1f} | {diff:.1e} |",
                  flush=True)


if __name__ == "__main__":
    main()
    sys.exit(0)
