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

``--phases`` times the banded estimate's two phases instead (:func:`agents.estimated_model.greedy_policy_phases`:
value iteration to ``1e-3``, then policy iteration with exact evaluations), each from zeros as the agents start it
and from the values of the same estimate one log (``--log-period`` steps) earlier, as a warm start would: the value
iteration's sweeps, the policy iteration's evaluations, milliseconds of each, and whether the two policies agree.

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

from agents import estimated_model as em  # noqa: E402
from agents import psrl_continuous, ucrl2  # noqa: E402
from agents.posteriors import normal_gamma_mean  # noqa: E402
from hardness.benchmark import sets  # noqa: E402
from jaxmdp.experiment import compilation, runner  # noqa: E402


#: agent name -> (agent, dense route (the policy estimate before :mod:`agents.estimated_model`, kept as the overflow
#: fallback), route on the observed next states)
ROUTES = {
    "ucrl2": (ucrl2.UCRL2, ucrl2._dense_policy, ucrl2.policy),
    "psrl_continuous": (psrl_continuous.PSRL_CONTINUOUS, psrl_continuous._dense_policy, psrl_continuous.policy),
}


#: agent name -> its estimated model on the observed next states, ``state -> (SparseKernel, R[S, A])``
MODELS = {
    "ucrl2": ucrl2.sparse_estimated_model,
    "psrl_continuous": lambda st: (psrl_continuous.posterior_mean_kernel(st), normal_gamma_mean(st.rewards)),
}


def phase_row(name: str, label: str, mdp, hp, steps: int, args) -> str:
    """One ``--phases`` row: the banded estimate from zeros and from the previous log's values."""
    agent = ROUTES[name][0]
    orders, width = runner._band(mdp, np.zeros(1, int))
    if orders is None:
        return f"| {name} | {label} | {mdp.n_states} | {steps} | no band |"
    before = jax.jit(lambda k: pcp.played(agent, mdp, hp, steps, k))(jax.random.key(0))
    after = jax.jit(lambda k, st: pcp.played(agent, mdp, hp, args.log_period, k, st))(jax.random.key(1), before)

    @jax.jit
    def phases(state, u0):
        state = state.replace(successors=state.successors.replace(order=orders[0], bandwidth=width))
        kernel, R = MODELS[name](state)
        return em.greedy_policy_phases(kernel, R, hp.policy_discount, state.action_mask, u0)

    zeros = jax.numpy.zeros(before.Q.shape[:1], before.Q.dtype)  # the agents' start
    u_prev = phases(before, zeros)[2].V  # the exact values of its policy, the start the agents hand on
    out, best = {}, {}
    for start, u0 in (("zeros", zeros), ("previous log", u_prev)):
        out[start] = jax.block_until_ready(phases(after, u0))
        best[start] = np.inf
    for _ in range(args.repeats):
        for start, u0 in (("zeros", zeros), ("previous log", u_prev)):
            t0 = time.perf_counter()
            jax.block_until_ready(phases(after, u0))
            best[start] = min(best[start], time.perf_counter() - t0)
    (p0, vi0, pi0), (p1, vi1, pi1) = out["zeros"], out["previous log"]
    same = bool(np.array_equal(np.asarray(p0), np.asarray(p1)))
    return (f"| {name} | {label} | {mdp.n_states} | {steps} | {int(vi0.iterations)} / {int(vi1.iterations)} | "
            f"{int(pi0.iterations)} / {int(pi1.iterations)} | {1e3 * best['zeros']:.1f} / "
            f"{1e3 * best['previous log']:.1f} | {best['zeros'] / best['previous log']:.1f}x | {same} |")


PHASE_HEADER = [
    "| agent | MDP | S | random steps | value-iteration sweeps: from zeros / previous log | policy-iteration "
    "evaluations | ms | speed-up | same policy |",
    "|---|---|---|---|---|---|---|---|---|",
]


def main(argv: list[str] | None = None) -> list[str]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--set", default="continuous ergodic")
    ap.add_argument("--agents", nargs="+", default=list(ROUTES), choices=list(ROUTES))
    ap.add_argument("--steps", type=int, nargs="+", default=[300, 5000, 50_000])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--phases", action="store_true", help="time the estimate's two phases, cold and warm")
    ap.add_argument("--log-period", type=int, default=100, help="steps between two logs (--phases)")
    ap.add_argument("--labels", nargs="+", help="only these MDPs of --set (default: each size bucket's largest)")
    ap.add_argument("--doc", type=Path, default=Path("docs/benchmarks/continuous_indicators.md"))
    compilation.add_cache_flag(ap)
    args = ap.parse_args(argv)
    compilation.setup_compilation(args.no_compile_cache)
    rows = []
    for name in args.agents:
        agent, dense, sparse = ROUTES[name]
        routes = {"dense": jax.jit(dense), "sparse": jax.jit(sparse), "banded": jax.jit(sparse)}
        for label in args.labels or pcp.bucket_labels(args.set):
            mdp = sets.instance(args.set, label).build(0)
            hp = agent.default_hparams
            if name == "psrl_continuous":  # the plan's buffer at the MDP's own psi, as the benchmark sizes it
                hp = hp.replace(max_psi=psrl_continuous.psi(hp, mdp.n_states, mdp.n_actions))
            if args.phases:
                for steps in args.steps:
                    rows.append(phase_row(name, label, mdp, hp, steps, args))
                    print(rows[-1], flush=True)
                continue
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
    header = PHASE_HEADER if args.phases else [
        "| agent | MDP | S | K | band | random steps | dense ms | observed next states ms | speed-up | states whose "
        "action differs | banded ms | speed-up over observed | states whose action differs |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    lines = [
        f"### {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}",
        "",
        f"`python {' '.join(sys.argv)}`: best of {args.repeats}, one member; jax {jax.__version__}, "
        f"{jax.default_backend()}, {platform.machine()}.",
        "",
        *header,
        *rows,
        "",
    ]
    with open(args.doc, "a") as f:
        f.write("\n".join(lines) + "\n")
    return rows


if __name__ == "__main__":
    main()
