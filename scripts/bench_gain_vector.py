"""Time ``dp.gain_vector`` (the runner's exact gain for continuous indicators) on the benchmark's largest
continuous MDPs, against the same function at a git revision (default ``main``), in one process: this tree's dense
elimination, and its banded one on the MDP's ``jaxmdp.gth.band_order`` (what the runner uses on a CPU).

For each MDP (``hardness.benchmark`` "continuous ergodic", seed 0) and each policy (a random deterministic one,
the gain-optimal one from ``dp.optimal_gain``, and that one with a fraction of its states' actions redrawn at random,
as a partly learnt Q-learning policy would be), both versions are compiled once and then called in alternation,
``--repeats`` times each; the best wall and the best process CPU time of each are reported, with the largest relative
difference of the two gain vectors (over the largest gain). Under load the best-of times, the CPU times and their
ratios are what to read (docs/benchmarks/continuous_indicators.md); the ratio columns are the baseline's time over
this tree's banded one. ``--compile`` also reports each version's
compile seconds (one ``jit(...).lower(...).compile()`` each, on the first MDP). ``--banded-baseline`` times the
baseline's banded route instead of its dense one (both banded routes unchecked, ``check_band=False``, as the runner
calls them, where the baseline has that option). ``--eliminate 32,1 32,4`` times
the blocked elimination alone at those ``block,stages`` settings instead.

    PYTHONPATH=$PWD python scripts/bench_gain_vector.py --labels MiniGridEmpty/prms_2 MiniGridEmpty/prms_3 \\
        MiniGridRooms/prms_1 --repeats 5
"""

from __future__ import annotations

import argparse
import inspect
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from hardness.benchmark import sets
from baseline_module import load_revision  # scripts/ is on the path of a script run as python scripts/NAME.py
from jaxmdp import dynamic_programming as dp
from jaxmdp import gth


def policies(mdp, rng: np.random.Generator, redrawn: float) -> dict[str, jax.Array]:
    S, A = mdp.n_states, mdp.n_actions
    best = np.asarray(jnp.argmax(dp.optimal_gain(mdp).policy, -1))
    partial = np.where(rng.random(S) < redrawn, rng.integers(0, A, S), best)
    out = dict(random=rng.integers(0, A, S), optimal=best, partly_learnt=partial)
    return {k: jax.nn.one_hot(jnp.asarray(v), A, dtype=mdp.R.dtype) for k, v in out.items()}


def best_times(fns: dict, args: tuple, repeats: int) -> dict[str, tuple[float, float]]:
    """Best wall and best process CPU seconds of each function over ``repeats`` alternating calls."""
    times = {k: (np.inf, np.inf) for k in fns}
    for _ in range(repeats):
        for k, f in fns.items():
            t, c = time.perf_counter(), time.process_time()
            jax.block_until_ready(f(*args))
            t, c = time.perf_counter() - t, time.process_time() - c
            times[k] = (min(times[k][0], t), min(times[k][1], c))
    return times


def eliminate_settings(args: argparse.Namespace) -> None:
    """Compile seconds and best wall / CPU seconds of the elimination alone, per ``block,stages`` setting."""
    print("| MDP | S | block | stages | compile s | best wall s | best CPU s |")
    print("|---|---|---|---|---|---|---|")
    for label in args.labels:
        mdp = sets.instance(args.set, label).build(0)
        pi = policies(mdp, np.random.default_rng(0), args.redrawn)["random"]
        P = dp.policy_matrix(mdp, pi)
        for setting in args.eliminate:
            block, stages = (int(x) for x in setting.split(","))
            t = time.perf_counter()
            f = jax.jit(lambda P, block=block, stages=stages: gth.gth_eliminate(P, block, stages)).lower(P).compile()
            compile_s = time.perf_counter() - t
            (wall, cpu), = best_times({setting: f}, (P,), args.repeats).values()
            print(f"| {label} | {mdp.n_states} | {block} | {stages} | {compile_s:.2f} | {wall:.4f} | {cpu:.4f} |",
                  flush=True)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--labels", nargs="+", default=["MiniGridEmpty/prms_2", "MiniGridEmpty/prms_3",
                                                   "MiniGridRooms/prms_1"], help="MDPs of the set (%(default)s)")
    p.add_argument("--set", default="continuous ergodic", help="benchmark set (%(default)s)")
    p.add_argument("--baseline", default="main", help="git revision timed against (%(default)s)")
    p.add_argument("--repeats", type=int, default=5, help="calls of each version per policy (%(default)s)")
    p.add_argument("--redrawn", type=float, default=0.2, help="fraction of redrawn actions (%(default)s)")
    p.add_argument("--banded-baseline", action="store_true", help="time the baseline's banded route")
    p.add_argument("--compile", action="store_true", help="also time each version's compilation")
    p.add_argument("--eliminate", nargs="*", default=[], metavar="BLOCK,STAGES",
                   help="only time jaxmdp.gth.gth_eliminate on each MDP's random policy matrix at these settings "
                        "(compile and best CPU seconds), e.g. 32,1 32,4 32,8")
    args = p.parse_args(argv)
    jax.config.update("jax_enable_compilation_cache", False)  # compile times are of real compilations
    if args.eliminate:
        eliminate_settings(args)
        return
    base = load_revision(args.baseline, "jaxmdp/dynamic_programming.py", "baseline_dynamic_programming")
    rng = np.random.default_rng(0)
    names = (args.baseline, "dense", "banded")
    print("| MDP | S | bandwidth | policy | " + " | ".join(f"{k} wall s" for k in names) + " | ratio | "
          + " | ".join(f"{k} CPU s" for k in names) + " | ratio | max rel. diff |")
    print("|---" * (2 * len(names) + 7) + "|")
    for q, label in enumerate(args.labels):
        mdp = sets.instance(args.set, label).build(0).strip()
        order, width = gth.band_order(mdp)
        order = jnp.asarray(order)
        unchecked = dict(check_band=False)
        base_band = dict(order=order, bandwidth=width) if args.banded_baseline else {}
        if args.banded_baseline and "check_band" in inspect.signature(base.gain_vector).parameters:
            base_band.update(unchecked)
        fns = {
            args.baseline: jax.jit(lambda m, pi, kw=base_band: base.gain_vector(m, pi, **kw)),
            "dense": jax.jit(lambda m, pi: dp.gain_vector(m, pi)),
            "banded": jax.jit(lambda m, pi, w=width: dp.gain_vector(m, pi, order=order, bandwidth=w, **unchecked)),
        }
        if args.compile and q == 0:
            pi = jax.nn.one_hot(jnp.zeros(mdp.n_states, int), mdp.n_actions, dtype=mdp.R.dtype)
            for k, f in fns.items():
                t = time.perf_counter()
                f.lower(mdp, pi).compile()
                print(f"compile {k} at S = {mdp.n_states}: {time.perf_counter() - t:.2f} s", flush=True)
        for name, pi in policies(mdp, rng, args.redrawn).items():
            out = {k: np.asarray(f(mdp, pi)) for k, f in fns.items()}  # compiles
            times = best_times(fns, (mdp, pi), args.repeats)
            a, b = out[args.baseline], out["banded"]
            diff = float(np.max(np.abs(a - b)) / np.max(np.abs(a)))
            walls = [times[k][0] for k in names]
            cpus = [times[k][1] for k in names]
            print(f"| {label} | {mdp.n_states} | {width} | {name} | " + " | ".join(f"{t:.4f}" for t in walls)
                  + f" | {walls[0] / walls[2]:.1f} | " + " | ".join(f"{t:.4f}" for t in cpus)
                  + f" | {cpus[0] / cpus[2]:.1f} | {diff:.1e} |", flush=True)


if __name__ == "__main__":
    main()
    sys.exit(0)
