"""The continuous indicators' exact gain of a policy at the benchmark's largest continuous MDPs: the runner's
evaluation against the dense elimination, in one process, interleaved, best of ``--reps`` (other processes share the
machine: read the ratios).

For each MDP (default: the 948-state MiniGridRooms of both continuous settings) and several deterministic policies
given by their action indices, as the runner hands them over (the greedy policy of UCRL2's policy estimate after
``--play`` uniformly random steps, a uniformly random policy and the optimal policy), the gain from every state by

* **runner**: :func:`jaxmdp.experiment.indicators.policy_values` as the runner calls it on a CPU: certified bounds on
  the successor lists first (:data:`~jaxmdp.experiment.indicators.ITERATIVE_GAIN_SWEEPS` sweeps,
  :data:`~jaxmdp.experiment.indicators.ITERATIVE_GAIN_GIVE_UP`), else the banded GTH elimination on the MDP's band
  order (:func:`jaxmdp.gth.band_order`, unchecked);
* **banded**: the banded elimination alone;
* **dense**: the dense ``O(S^3)`` GTH elimination (:func:`jaxmdp.dynamic_programming.gain_vector` without an order).

The largest difference from the dense gains is printed in units of the indicators' tolerance ``1e-6 (1 + |g|)``.

    python benchmarks/bench_indicators.py [--reps 3] [--play 20000] [--update-docs]
    python benchmarks/bench_indicators.py --smoke
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

import agents
import jaxmdp
from agents import ucrl2
from hardness.benchmark import sets
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment import compilation, indicators
from jaxmdp.experiment.agent_interface import spec_of
from jaxmdp.gth import band_order

import _common

NAME = "bench_indicators"
MDPS = (("continuous ergodic", "MiniGridRooms/prms_1"), ("continuous communicating", "MiniGridRooms/prms_0"))


def build_mdp(set_name: str, label: str, smoke: bool) -> jaxmdp.MDP:
    """The benchmark's MDP (seed 0), or at ``smoke`` size a small one."""
    if smoke:
        return jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=4)
    return sets.instance(set_name, label).build(0)


def ucrl2_greedy(mdp: jaxmdp.MDP, steps: int, order, width: int) -> jax.Array:
    """The action indices of UCRL2's policy estimate after ``steps`` uniformly random steps (``update`` only)."""
    agent = agents.get("ucrl2")
    state = _common.random_play(agent, mdp, spec_of(mdp, 500_000, order, width), agent.default_hparams, steps,
                                jax.random.key(0))
    return jnp.argmax(ucrl2.warm_policy(state, None)[0], axis=-1).astype(jnp.int32)


def optimal_actions(mdp: jaxmdp.MDP) -> jax.Array:
    """The action indices of a gain-optimal policy (:func:`jaxmdp.dynamic_programming.optimal_gain`)."""
    pi = dp.optimal_gain(mdp).policy
    return (pi if pi.ndim == 1 else jnp.argmax(pi, axis=-1)).astype(jnp.int32)


def measure(mdp: jaxmdp.MDP, label: str, play: int, reps: int) -> list[dict]:
    """The rows of one MDP (module docstring)."""
    order, width = band_order(mdp)
    order = jnp.asarray(order)
    S, A = mdp.n_states, mdp.n_actions
    policies = {
        f"UCRL2's estimate after {play:,} steps": ucrl2_greedy(mdp, play, order, width),
        "uniformly random": jax.random.randint(jax.random.key(3), (S,), 0, int(np.sum(np.asarray(mdp.action_mask)))),
        "optimal": optimal_actions(mdp),
    }
    band = dict(order=order, bandwidth=width, check_band=False)
    fns = {
        "runner": jax.jit(lambda p: indicators.policy_values(mdp, p, indicators.ITERATIVE_GAIN_SWEEPS,
                                                             give_up=indicators.ITERATIVE_GAIN_GIVE_UP, **band)),
        "banded": jax.jit(lambda p: indicators.policy_values(mdp, p, **band)),
        "dense": jax.jit(lambda p: indicators.policy_values(mdp, p)),
    }
    bounds = jax.jit(functools.partial(dp.successor_gain_bounds, max_sweeps=indicators.ITERATIVE_GAIN_SWEEPS,
                                       give_up=indicators.ITERATIVE_GAIN_GIVE_UP))
    rows = []
    for name, pi in policies.items():
        best = _common.interleaved_best(fns, (pi,), reps)
        dense = np.asarray(fns["dense"](pi), np.float64)
        tol = 1e-6 * (1 + np.abs(dense))
        diff = {k: float(np.max(np.abs(np.asarray(fns[k](pi), np.float64) - dense) / tol))
                for k in ("runner", "banded")}
        b = bounds(mdp, pi)
        rows.append(dict(mdp=label, S=S, A=A, w=width, policy=name, certified=bool(b.certified),
                         sweeps=int(b.sweeps), **{f"{k}_s": v for k, v in best.items()},
                         **{f"{k}_diff": v for k, v in diff.items()}))
        r = rows[-1]
        print(f"{label} ({S} states, band {width}), {name}: runner {r['runner_s'] * 1e3:.2f} ms "
              f"(bounds {'certified' if r['certified'] else 'not certified'} after {r['sweeps']} sweeps), banded "
              f"{r['banded_s'] * 1e3:.2f} ms, dense {r['dense_s'] * 1e3:.1f} ms; max difference "
              f"{max(diff.values()):.2f} tolerances", flush=True)
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=3, help="timed rounds (best is kept)")
    ap.add_argument("--play", type=int, default=20000, help="random steps before UCRL2's estimate (%(default)s)")
    _common.add_common_args(ap)
    args = ap.parse_args(argv)
    mdps = MDPS[:1] if args.smoke else MDPS
    if args.smoke:
        args.reps, args.play = 1, 200
    cache_folder, compile_stats = compilation.setup_compilation(args.no_compile_cache)
    t_script = time.perf_counter()
    rows = [r for set_name, label in mdps for r in measure(build_mdp(set_name, label, args.smoke),
                                                           f"{set_name}, {label}", args.play, args.reps)]
    _common.publish(NAME, "Continuous indicators: the exact gain of a policy", body(rows, args), args, argv)
    print(compilation.time_report(time.perf_counter() - t_script, compile_stats.snapshot(), cache_folder),
          file=sys.stderr)
    return 0


def body(rows: list[dict], args) -> list[str]:
    """The table's lines."""
    lines = [
        f"One process, interleaved, best of {args.reps}; wall ms per call (each its own program). Difference: the "
        "largest over the states from the dense gains, in units of the indicators' tolerance `1e-6 (1 + |g|)`.",
        "",
        "| MDP | S | band | policy | bounds | runner ms | banded ms | dense ms | dense / runner | dense / banded "
        "| difference |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['mdp']} | {r['S']} | {r['w']} | {r['policy']} | "
            f"{'certified' if r['certified'] else 'not certified'} ({r['sweeps']}) | {r['runner_s'] * 1e3:.2f} | "
            f"{r['banded_s'] * 1e3:.2f} | {r['dense_s'] * 1e3:.1f} | {r['dense_s'] / r['runner_s']:.1f}x | "
            f"{r['dense_s'] / r['banded_s']:.1f}x | {max(r['runner_diff'], r['banded_diff']):.2f} |")
    return lines


if __name__ == "__main__":
    sys.exit(main())
