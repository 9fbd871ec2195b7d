"""The floor that exact posterior draws put under episodic PSRL's share of the full benchmark (issue "Performance",
item 3: "the dense Dirichlet draw of exact PSRL stays if the algorithm needs it: say so with a measurement").

Episodic PSRL (Osband et al. 2013; paper §3.3) draws, at the start of every episode, one transition kernel from its
posterior ``P(.|s,a) ~ Dirichlet(1/S + N(s,a,.))``: ``S x A x S`` Gamma variates per member and episode, whatever
the sampler. With ``H`` the member's horizon, a member of the full run (500 000 steps) makes ``500 000 / H`` draws,
each over its batch's padded ``S`` and ``A``. This script

1. counts those Gamma variates for every episodic PSRL batch of :func:`hardness.benchmark.run.plan` (20 seeds, both
   episodic settings), padded as the runner pads them and, for comparison, at each MDP's own size;
2. times one draw (:func:`agents.posteriors.dirichlet_sample`, the agent's own sampler and normalisation) on one
   core (the process's CPU affinity, where the platform has one), inside one compiled program, as the runner pays
   it (:func:`scripts.profile_continuous_plans.in_program_seconds`), on a posterior with ``N(s,a,.) = 10 P(.|s,a)``
   rounded up over each pair's successors (shapes at and above 1) besides the ``1/S`` prior (shapes far below 1,
   the boosted branch);
3. writes the draws' seconds alone, spread perfectly over the full run's cores (one shard per core): a lower bound
   on what episodic PSRL costs with any implementation that draws the posterior exactly (the cheapest timed variate
   stands for all);
4. prints, for each of the four settings and each ``--buckets`` count, how much the size buckets pad the dense model
   work of a step (:func:`padding_factor`), which is what :data:`hardness.benchmark.run.PLANNING_BUCKETS` trims.

    python scripts/bench_psrl_draw_floor.py --out results/psrl_draw_floor --buckets 4 8
"""

from __future__ import annotations

import os

#: The cores the full run spreads its shards over (one lockstep program per core, as scripts/run_benchmark.py runs).
RUN_CORES = os.cpu_count() or 1

if __name__ == "__main__" and hasattr(os, "sched_setaffinity"):
    # The draw is timed on one core (set before JAX starts its threads). A program of its own spreads the draw over
    # every core, while in the full run each core runs a shard of its own: timed on both cores of the 2-core
    # machine and then divided by the cores again, the floor came out 1.5-1.8x too low (docs/benchmarks/
    # bench_psrl_draw_floor.md, 2026-11-30).
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})

import argparse  # noqa: E402
import functools  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from agents.posteriors import dirichlet_sample  # noqa: E402
import jaxmdp  # noqa: E402
from hardness.benchmark import run, sets  # noqa: E402
from jaxmdp.experiment import compilation  # noqa: E402
from scripts.profile_continuous_plans import in_program_seconds  # noqa: E402

SETTINGS = ("episodic ergodic", "episodic communicating")
FULL = dict(seeds=tuple(range(20)), n_steps=500_000, n_buckets=4)


@functools.cache
def seed0_mdps(set_name: str) -> dict[str, jaxmdp.MDP]:
    """The set's MDPs of seed 0 by label (built once per process: both counts below and the tests read them)."""
    return {inst.label: inst.build(0) for inst in sets.instances(set_name)}


def draw_counts(settings=SETTINGS, n_steps: int = FULL["n_steps"], n_buckets: int = FULL["n_buckets"]) -> list[dict]:
    """Per episodic PSRL batch of the full plan: members, padded ``S`` and ``A``, and the Gamma variates its draws
    need, padded (``sum_m n_steps / H_m x S_pad^2 A_pad``) and at each member's own size (``S_m^2 A_m``)."""
    config = run.RunConfig(sets=tuple(settings), agents=("psrl_episodic",), seeds=FULL["seeds"], n_steps=n_steps,
                           n_buckets=n_buckets, agent_buckets={})
    _, batches = run.plan(config)
    rows = []
    for set_name in settings:
        sizes = {label: (m.n_states, m.n_actions, int(m.H)) for label, m in seed0_mdps(set_name).items()}
        for b in (b for b in batches if b.set_name == set_name):
            S_pad = max(sizes[label][0] for label, _ in b.members)
            A_pad = max(sizes[label][1] for label, _ in b.members)
            episodes = [n_steps / sizes[label][2] for label, _ in b.members]
            own = [n_steps / H * S * S * A for S, A, H in (sizes[label] for label, _ in b.members)]
            rows.append(dict(batch=b.id, members=len(b.members), S_pad=S_pad, A_pad=A_pad,
                             episodes=float(np.sum(episodes)), gammas_padded=float(np.sum(episodes)) * S_pad**2 * A_pad,
                             gammas_own=float(np.sum(own))))
    return rows


def padding_factor(set_name: str, n_buckets: int) -> float:
    """``sum_m S_b^2 A_b / H_m`` over the set's MDPs ``m`` in their buckets ``b`` (:func:`jaxmdp.size_buckets`), over
    ``sum_m S_m^2 A_m / H_m`` (``H = 1`` when continuous): how much the buckets pad the dense model work of a step."""
    mdps = list(seed0_mdps(set_name).values())
    per_step = lambda S, A, m: S * S * A / (m.H if m.episodic else 1)  # noqa: E731
    own = sum(per_step(m.n_states, m.n_actions, m) for m in mdps)
    padded = 0.0
    for group in jaxmdp.size_buckets(mdps, n_buckets):
        S, A = max(mdps[i].n_states for i in group), max(mdps[i].n_actions for i in group)
        padded += sum(per_step(S, A, mdps[i]) for i in group)
    return padded / own


def posterior_concentration(label: str, set_name: str, visits: int = 10) -> jax.Array:
    """``1/S + ceil(visits P(.|s,a))`` of an MDP of the set: the concentration the draw is timed on."""
    mdp = seed0_mdps(set_name)[label]
    S = mdp.T.shape[0]
    return jnp.asarray(1.0 / S + np.ceil(visits * np.asarray(mdp.T)), jnp.float32)


def seconds_per_gamma(alpha: jax.Array, members: int, repeats: int) -> float:
    """Seconds per Gamma variate of ``members`` draws of ``Dirichlet(alpha)`` rows in one program."""
    alphas = jnp.broadcast_to(alpha, (members, *alpha.shape))
    keys = jax.random.split(jax.random.key(0), members)
    draw = jax.vmap(lambda k, a: dirichlet_sample(k, a))
    return in_program_seconds(draw, keys, alphas, calls=4, repeats=repeats) / alphas.size


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, required=True, help="folder for floor.json")
    p.add_argument("--timed", nargs="+", default=["Taxi/prms_0", "MiniGridEmpty/prms_0"], metavar="LABEL",
                   help="episodic ergodic MDPs whose draws are timed (default: %(default)s)")
    p.add_argument("--buckets", type=int, nargs="+", default=[FULL["n_buckets"]], metavar="N",
                   help="size buckets per setting to count the padded draws for (default: the full run's, %(default)s)")
    p.add_argument("--members", type=int, default=10, help="draws per timed call (%(default)s)")
    p.add_argument("--repeats", type=int, default=3, help="best of this many loops (%(default)s)")
    compilation.add_cache_flag(p)
    args = p.parse_args(argv)
    compilation.setup_compilation(args.no_compile_cache)
    args.out.mkdir(parents=True, exist_ok=True)

    timed = []
    for label in args.timed:
        alpha = posterior_concentration(label, SETTINGS[0])
        s = seconds_per_gamma(alpha, args.members, args.repeats)
        timed.append(dict(label=label, shape=list(alpha.shape), ns_per_gamma=s * 1e9))
        print(f"{label} {tuple(alpha.shape)}: {s * 1e9:.2f} ns per Gamma variate (in one program)", flush=True)
    ns = min(t["ns_per_gamma"] for t in timed)  # a floor: the cheapest variate measured

    cores = RUN_CORES
    timed_on = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else cores
    if timed_on > 1:
        print(f"timed on {timed_on} cores (no CPU affinity here): the hours below understate the floor", flush=True)
    counted = {}
    for n_buckets in args.buckets:
        rows = draw_counts(n_buckets=n_buckets)
        for r in rows:
            r["hours_padded"] = r["gammas_padded"] * ns * 1e-9 / 3600 / cores
            r["hours_own"] = r["gammas_own"] * ns * 1e-9 / 3600 / cores
            print(f"{n_buckets} buckets, {r['batch']}: {r['members']} members, S {r['S_pad']}, A {r['A_pad']}, "
                  f"{r['gammas_padded']:.3g} Gamma variates -> {r['hours_padded']:.2f} h ({r['hours_own']:.2f} h "
                  "unpadded)", flush=True)
        total = {k: sum(r[k] for r in rows) for k in ("gammas_padded", "gammas_own", "hours_padded", "hours_own")}
        print(f"{n_buckets} buckets: episodic PSRL's draws alone, both episodic settings, {cores} cores: "
              f"{total['hours_padded']:.2f} h ({total['hours_own']:.2f} h without padding) at {ns:.2f} ns per Gamma "
              "variate", flush=True)
        counted[n_buckets] = dict(batches=rows, total=total)
    padding = {s: {n: padding_factor(s, n) for n in args.buckets} for s in sets.SETTINGS}
    for set_name, factors in padding.items():
        print(f"{set_name}: dense model work per step padded by " + ", ".join(
            f"{f:.2f} ({n} buckets)" for n, f in factors.items()), flush=True)
    (args.out / "floor.json").write_text(json.dumps(dict(timed=timed, ns_per_gamma=ns, cores=cores,
                                                         timed_on_cores=timed_on, buckets=counted,
                                                         padding=padding, command=" ".join(sys.argv)), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
