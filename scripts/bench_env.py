"""Benchmark: random-action environment steps per second, for 1 to 8192 parallel environments.

Each measurement is one jitted ``lax.scan`` of ``reset``-free random-action steps vmapped over environments (keys)
of one MDP; compile time is measured separately. Writes ``results/bench_env.{md,csv}``.

    python scripts/bench_env.py                 # S~100 and S~1000 MDPs, 1/64/1024/8192 environments
    python scripts/bench_env.py --quick         # smaller step counts
"""

from __future__ import annotations

import argparse
import csv
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp

import jaxmdp


def benchmark_mdps() -> list[tuple[str, jaxmdp.MDP]]:
    """An S~100 and an S~1000 MDP with stochastic dynamics and Beta rewards (SimpleGrid if registered), and the
    S~100 one with point-mass rewards (no reward draw is compiled: the cost of the dynamics alone)."""
    if "SimpleGrid" in jaxmdp.families():
        make = lambda size, beta=True: jaxmdp.make(  # noqa: E731
            "SimpleGrid", episodic=False, seed=0, size=size, p_lazy=0.1, p_rand=0.1, make_reward_stochastic=beta
        )
        return [
            ("SimpleGrid size 10", make(10)),
            ("SimpleGrid size 10, point-mass rewards", make(10, False)),
            ("SimpleGrid size 32", make(32)),
        ]
    return [("RiverSwim size 100", make(100)), ("RiverSwim size 1000", make(1000))]


def make_runner(n_envs: int, n_steps: int):
    def run(key, mdp):
        keys = jax.random.split(key, n_envs)
        _, states = jax.vmap(jaxmdp.reset, in_axes=(0, None))(keys, mdp)

        def body(carry, k):
            states, total = carry
            ks = jax.random.split(k, n_envs)

            def one(key, state):
                k_act, k_step = jax.random.split(key)
                a = jaxmdp.sample_action(k_act, mdp)
                _, state, r, *_ = jaxmdp.step(k_step, state, a, mdp)
                return state, r

            states, r = jax.vmap(one)(ks, states)
            return (states, total + jnp.sum(r)), None

        (_, total), _ = jax.lax.scan(body, (states, jnp.zeros(())), jax.random.split(key, n_steps))
        return total

    return jax.jit(run)


def measure(mdp: jaxmdp.MDP, n_envs: int, n_steps: int, repeats: int = 3) -> tuple[float, float]:
    run = make_runner(n_envs, n_steps)
    key = jax.random.key(0)
    t0 = time.perf_counter()
    run.lower(key, mdp).compile()
    compile_s = time.perf_counter() - t0
    run(key, mdp).block_until_ready()
    best = float("inf")
    for i in range(repeats):
        t0 = time.perf_counter()
        run(jax.random.key(i + 1), mdp).block_until_ready()
        best = min(best, time.perf_counter() - t0)
    return n_envs * n_steps / best, compile_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 64, 1024, 8192])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", type=Path, default=Path("results"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    budget = 2_000_000 if args.quick else 20_000_000  # environment steps per measurement

    rows = []
    for name, mdp in benchmark_mdps():
        mdp = mdp.strip()
        for n in args.envs:
            n_steps = max(100, min(20_000, budget // n))
            sps, compile_s = measure(mdp, n, n_steps)
            rows.append(dict(mdp=name, n_states=mdp.n_states, n_envs=n, steps_per_s=sps, compile_s=compile_s))
            print(f"{name:22s} S={mdp.n_states:5d} envs={n:5d}: {sps / 1e6:8.3f} M steps/s (compile {compile_s:.1f} s)")

    with (args.out / "bench_env.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = [
        "# Environment throughput (random actions)",
        "",
        f"jax {jax.__version__}, backend {jax.default_backend()}, {platform.processor() or platform.machine()}",
        "",
        "| MDP | S | parallel envs | M steps/s | compile s |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['mdp']} | {r['n_states']} | {r['n_envs']} | {r['steps_per_s'] / 1e6:.3f} | {r['compile_s']:.2f} |"
        for r in rows
    ]
    (args.out / "bench_env.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out / 'bench_env.md'}")


if __name__ == "__main__":
    main()
