"""Benchmark: the continuous model-based agents' per-log policy estimate on their observed next states against the
dense route it replaced.

At every log the runner asks each continuous model-based agent for its policy estimate: the greedy policy of the
discounted (0.99) optimal values of its estimated MDP (UCRL2: empirical; PSRL: posterior mean; docs/agents.md §3,
§4). The dense route (:func:`agents.tabular_common.discounted_greedy_policy` of the dense kernel) backs up through
``[S, A, S]`` kernels; the agents' ``policy`` backs up through the ``K`` observed next states of each pair
(:mod:`agents.estimated_model`), and the banded route is the same with the MDP's band order (which the runner hands
to the agents where it has one, :func:`jaxmdp.experiment.runner._band`; "-" where it has none): banded evaluations
instead of dense solves. For the largest MDP of each size bucket of "continuous ergodic", the agent's state after
``--steps`` uniformly random steps (``update`` only), the routes jitted on one member, called alternately
``--repeats`` times in one process (best of each); the table also counts the states whose greedy action differs from
the dense route's.

    python scripts/bench_policy_estimate.py --agents ucrl2 psrl_continuous --steps 300 5000 50000

Prints the table and appends it, with the command, to ``--doc`` (docs/benchmarks/continuous_indicators.md).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import profile_continuous_plans as pcp  # noqa: E402

from agents import psrl_continuous, ucrl2  # noqa: E402
from hardness.benchmark import sets  # noqa: E402
from jaxmdp.experiment import compilation, runner  # noqa: E402


#: agent name -> (agent, dense route (the policy estimate before :mod:`agents.estimated_model`, kept as the overflow
#: fallback), route on the observed next states)
ROUTES = {
    "ucrl2": (ucrl2.UCRL2, ucrl2._dense_policy, ucrl2.policy),
    "psrl_continuous": (psrl_continuous.PSRL_CONTINUOUS, psrl_continuous._dense_policy, psrl_continuous.policy),
}


def main(argv: list[str] | None = None) -> list[str]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--set", default="continuous ergodic")
    ap.add_argument("--agents", nargs="+", default=list(ROUTES), choices=list(ROUTES))
    ap.add_argument("--steps", type=int, nargs="+", default=[300, 5000, 50_000])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--doc", type=Path, default=Path("docs/benchmarks/continuous_indicators.md"))
    compilation.add_cache_flag(ap)
    args = ap.parse_args(argv)
    compilation.setup_compilation(args.no_compile_cache)
    rows = []
    for name in args.agents:
        agent, dense, sparse = ROUTES[name]
        routes = {"dense": jax.jit(dense), "sparse": jax.jit(sparse), "banded": jax.jit(sparse)}
        for label in pcp.bucket_labels(args.set):
            mdp = next(i for i in sets.instances(args.set) if i.label == label).build(0)
            hp = agent.default_hparams
            if name == "psrl_continuous":  # the plan's buffer at the MDP's own psi, as the benchmark sizes it
                hp = hp.replace(max_psi=psrl_continuous.psi(hp, mdp.n_states, mdp.n_actions))
            orders, width = runner._band(mdp, np.zeros(1, int))
            for steps in args.steps:
                state = jax.jit(lambda k: pcp.played(agent, mdp, hp, steps, k))(jax.random.key(0))
                states = {"dense": state, "sparse": state}
                if orders is not None:
                    states["banded"] = state.replace(
                        successors=state.successors.replace(order=orders[0], bandwidth=width))
                out = {r: jax.block_until_ready(routes[r](x)) for r, x in states.items()}
                best = dict.fromkeys(states, np.inf)
                for _ in range(args.repeats):
                    for r, x in states.items():
                        t0 = time.perf_counter()
                        jax.block_until_ready(routes[r](x))
                        best[r] = min(best[r], time.perf_counter() - t0)
                differ = {r: int(np.sum(np.any(np.asarray(out["dense"]) != np.asarray(o), axis=-1)))
                          for r, o in out.items()}
                banded = (f"{1e3 * best['banded']:.1f} | {best['sparse'] / best['banded']:.1f}x | {differ['banded']}"
                          if "banded" in best else "- | - | -")
                row = (f"| {name} | {label} | {mdp.n_states} | {mdp.max_successors} | {width or '-'} | {steps} | "
                       f"{1e3 * best['dense']:.1f} | {1e3 * best['sparse']:.1f} | "
                       f"{best['dense'] / best['sparse']:.1f}x | {differ['sparse']} | {banded} |")
                print(row, flush=True)
                rows.append(row)
    lines = [
        f"### {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}",
        "",
        f"`python {' '.join(sys.argv)}`: best of {args.repeats}, one member; jax {jax.__version__}, "
        f"{jax.default_backend()}, {platform.machine()}.",
        "",
        "| agent | MDP | S | K | band | random steps | dense ms | observed next states ms | speed-up | states whose "
        "action differs | banded ms | speed-up over observed | states whose action differs |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        *rows,
        "",
    ]
    with open(args.doc, "a") as f:
        f.write("\n".join(lines) + "\n")
    return rows


if __name__ == "__main__":
    main()
