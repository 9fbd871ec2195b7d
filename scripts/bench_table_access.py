"""Benchmark: the episodic Q-learning update with its table reads and writes through one flat index (as
``agents.q_learning_episodic.update`` does, :func:`agents.tabular_common.read_at` / ``write_at``) against the same
update with ``table[h, s, a]`` indexing (the previous code, kept here as :func:`update_multi_index`).

One jitted ``lax.scan`` of ``--steps`` updates vmapped over ``--members`` members of RiverSwim-25 (episodic), on
transitions drawn before the loop (so only the update is timed); the variants interleaved ``--repeats`` times, best
of each, in one process. Also checks that both give the same tables bit for bit. Prints a table and appends it, with
the command, to ``docs/benchmarks/bench_table_access.md``.

    python scripts/bench_table_access.py
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import jaxmdp
from agents import q_learning_episodic as ql
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--members", type=int, default=1024)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--doc", type=Path, default=Path("docs/benchmarks/bench_table_access.md"))
    compilation.add_cache_flag(ap)
    args = ap.parse_args()
    compilation.setup_compilation(args.no_compile_cache)
    M, T = args.members, args.steps
    mdp = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=25, p_lazy=0.05, make_reward_stochastic=True,
                      randomize_actions=False)
    spec = spec_of(mdp, T)
    state = jax.vmap(lambda k: ql.init(k, spec, ql.QLearningEpisodicHParams()))(jax.random.split(jax.random.key(0), M))
    H, S, A = state.q.shape[-3:]
    k = jax.random.split(jax.random.key(1), 4)
    trs = Transition(
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
    outs = {name: jax.block_until_ready(run(trs, state)) for name, run in variants.items()}
    (a, b) = outs.values()
    same = bool(np.array_equal(a.q, b.q) and np.array_equal(a.stats, b.stats))
    best = dict.fromkeys(variants, float("inf"))
    for _ in range(args.repeats):
        for name, run in variants.items():
            t0 = time.perf_counter()
            jax.block_until_ready(run(trs, state))
            best[name] = min(best[name], time.perf_counter() - t0)
    ns = {name: 1e9 * v / (M * T) for name, v in best.items()}
    base = ns["table[h, s, a] (previous)"]
    lines = [
        f"## {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}",
        "",
        f"`python {' '.join(sys.argv)}`: {M} members, {T} updates, best of {args.repeats}; jax {jax.__version__}, "
        f"{jax.default_backend()}, {platform.machine()}. Same tables bit for bit: {same}.",
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
