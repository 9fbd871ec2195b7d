"""Benchmark: the episodic Q-learning update with its table reads and writes through one flat index (as
``agents.q_learning_episodic.update`` does, :func:`agents.tabular_common.read_at` / ``write_at``) against the same
update with ``table[h, s, a]`` indexing (the previous code, kept here as :func:`update_multi_index`).

One jitted ``lax.scan`` of ``--steps`` updates vmapped over ``--members`` members of one of the benchmark MDPs of
``scripts/bench_agents.py`` (``--family``, episodic), on transitions drawn before the loop (so only the update is
timed); the variants interleaved ``--repeats`` times, best of each, in one process. Also checks that both give the
same tables bit for bit. Prints a table and appends it, with the command, to
``docs/benchmarks/bench_table_access.md``.

``--floor`` adds two variants that bound what any update with these tables costs: the update's memory traffic alone
(:func:`bare_access`: the same three row reads and two writes at the same indices, with only the arithmetic that
keeps them live) and the scan over the transitions with no table at all (:func:`no_table`). ``--trajectories``
draws the transitions from uniformly random episodes of the MDP (:func:`random_episodes`: the rows an exploring
agent visits, in the order it visits them) instead of uniformly at random over ``(h, s, a, s')``. Time the floor on
one core, as the runner runs one shard per core: ``taskset -c 0 python scripts/bench_table_access.py ...``.

    python scripts/bench_table_access.py
    taskset -c 0 python scripts/bench_table_access.py --family Taxi --floor --trajectories
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import jaxmdp
from agents import q_learning_episodic as ql
from agents.tabular_common import read_at, write_at
from bench_agents import BENCH_MDPS
from bench_doc import interleaved_best
from jaxmdp.experiment import compilation
from jaxmdp.experiment.agent_interface import Transition, spec_of


def update_multi_index(state: ql.QLearningEpisodicState, tr: Transition) -> ql.QLearningEpisodicState:
    """``ql.update`` (paper rules) with ``table[h, s, a]`` gathers and scatters: the code before the flat index."""
    h, s, a = tr.h, tr.obs, tr.action
    row = state.stats[h, s, a]
    t = row[ql._N] + 1.0
    H = state.horizon
    alpha = jnp.maximum(state.hparams.min_at, (H + 1.0) / (H + t))
    i = jnp.minimum(h + 1, state.q.shape[0] - 1)
    v_next = ql.table_values(state.q[i, tr.next_obs], state.stats[i, tr.next_obs], state.action_mask, H)
    v_next = jnp.where(h + 1 < H, v_next, 0.0)
    sum_v, sum_v2 = row[ql._SUM_V] + v_next, row[ql._SUM_V2] + v_next**2
    b, beta = ql.bonus(state, t, sum_v, sum_v2, row[ql._BETA], alpha)
    q = (1.0 - alpha) * state.q[h, s, a] + alpha * (tr.reward + v_next + b)
    return state.replace(
        q=state.q.at[h, s, a].set(q), stats=state.stats.at[h, s, a].set(jnp.stack([t, sum_v, sum_v2, beta]))
    )


def bare_access(state: ql.QLearningEpisodicState, tr: Transition) -> ql.QLearningEpisodicState:
    """The memory traffic of :func:`agents.q_learning_episodic.update` and the act before it, and nothing else:
    ``Q_h(s, .)`` (the act's row, which holds the updated entry), the statistics row of ``(h, s, a)``,
    ``Q_{h+1}(s', .)`` (the next value), then the writes of ``Q_h(s, a)`` and the statistics row. The values written
    depend on the rows read (so none is dead code) through one add and one max."""
    h, s, a = tr.h, tr.obs, tr.action
    row = read_at(state.q, h, s)
    stats = read_at(state.stats, h, s, a)
    v_next = jnp.max(read_at(state.q, jnp.minimum(h + 1, state.q.shape[0] - 1), tr.next_obs))
    q = row[a] + v_next
    return state.replace(q=write_at(state.q, q, h, s, a), stats=write_at(state.stats, stats + q, h, s, a))


def no_table(state: ql.QLearningEpisodicState, tr: Transition) -> ql.QLearningEpisodicState:
    """The scan's own cost: reads the transition and carries one number, touching no table."""
    x = tr.h + tr.obs + tr.action + tr.next_obs
    return state.replace(horizon=state.horizon + x.astype(state.horizon.dtype) + tr.reward)


def random_episodes(key: jax.Array, mdp, members: int, steps: int) -> Transition:
    """``[steps, members]`` transitions of uniformly random actions on ``mdp`` (episodes back to back, each member
    from its own start): the rows an exploring agent reads, in the order it reads them."""

    def one(k):
        def step(carry, k_t):
            obs, env = carry
            k_a, k_s = jax.random.split(k_t)
            a = jaxmdp.sample_action(k_a, mdp)
            nxt, env2, r, term, _, info = jaxmdp.step(k_s, env, a, mdp)
            tr = Transition(obs=obs, action=a, reward=r, next_obs=info["final_observation"], h=env.h,
                            terminated=term)
            return (nxt, env2), tr

        k0, k1 = jax.random.split(k)
        return jax.lax.scan(step, jaxmdp.reset(k0, mdp), jax.random.split(k1, steps))[1]

    return jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1), jax.vmap(one)(jax.random.split(key, members)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--members", type=int, default=1024)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--family", choices=sorted(f for f, e in BENCH_MDPS if e), default="RiverSwim",
                    help="the episodic benchmark MDP of scripts/bench_agents.py (default RiverSwim-25)")
    ap.add_argument("--floor", action="store_true", help="also time the bare table traffic and the bare scan")
    ap.add_argument("--trajectories", action="store_true",
                    help="transitions from uniformly random episodes instead of uniform (h, s, a, s')")
    ap.add_argument("--doc", type=Path, default=Path("docs/benchmarks/bench_table_access.md"))
    compilation.add_cache_flag(ap)
    args = ap.parse_args()
    compilation.setup_compilation(args.no_compile_cache)
    M, T = args.members, args.steps
    mdp = jaxmdp.make(args.family, episodic=True, seed=0, **BENCH_MDPS[(args.family, True)])
    spec = spec_of(mdp, T)
    state = jax.vmap(lambda k: ql.init(k, spec, ql.QLearningEpisodicHParams()))(jax.random.split(jax.random.key(0), M))
    H, S, A = state.q.shape[-3:]
    k = jax.random.split(jax.random.key(1), 4)
    trs = random_episodes(k[0], mdp, M, T) if args.trajectories else Transition(
        obs=jax.random.randint(k[0], (T, M), 0, S), action=jax.random.randint(k[1], (T, M), 0, A),
        reward=jax.random.uniform(k[2], (T, M)), next_obs=jax.random.randint(k[3], (T, M), 0, S),
        h=jax.random.randint(k[0], (T, M), 0, int(mdp.horizon)), terminated=jnp.zeros((T, M), bool),
    )

    def program(update):
        def run(trs, state):
            return jax.lax.scan(lambda st, tr: (jax.vmap(update)(st, tr), None), state, trs)[0]
        return jax.jit(run).lower(trs, state).compile()

    variants = {"flat index (agents.q_learning_episodic.update)": program(ql.update),
                "table[h, s, a] (previous)": program(update_multi_index)}
    if args.floor:
        variants |= {"reads and writes alone (bare_access)": program(bare_access),
                     "no table (no_table)": program(no_table)}
    a, b = (run(trs, state) for run in list(variants.values())[:2])
    same = bool(np.array_equal(a.q, b.q) and np.array_equal(a.stats, b.stats))
    best = interleaved_best(variants, (trs, state), args.repeats)
    ns = {name: 1e9 * v / (M * T) for name, v in best.items()}
    draws = "random episodes" if args.trajectories else "uniform (h, s, a, s')"
    base = ns["table[h, s, a] (previous)"]
    lines = [
        f"## {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}",
        "",
        f"`python {' '.join(sys.argv)}`: {args.family} (H, S, A = {H}, {S}, {A}; tables "
        f"{(state.q.nbytes + state.stats.nbytes) / 1e6:.0f} MB), {M} members, {T} updates "
        f"({draws}), best of {args.repeats}, "
        f"{len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count()} core(s); jax "
        f"{jax.__version__}, {jax.default_backend()}, {platform.machine()}. Same tables bit for bit: {same}.",
        "",
        "| update | ns per member-update | against table[h, s, a] |",
        "|---|---|---|",
        *(f"| {name} | {v:.1f} | {base / v:.2f}x |" for name, v in ns.items()),
        "",
    ]
    print("\n".join(lines))
    if not args.doc.exists():
        args.doc.write_text("# Table reads and writes of the episodic Q-learning update (scripts/bench_table_access.py)"
                            "\n\n")
    with open(args.doc, "a") as f:
        f.write("\n".join(lines) + "\n")
    if not same:
        raise SystemExit("the two updates gave different tables")


if __name__ == "__main__":
    main()
