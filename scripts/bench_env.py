"""Benchmark: random-action environment steps per second, for 1 to 8192 parallel environments, and against gymnax.

Each measurement is one jitted ``lax.scan`` of ``reset``-free random-action steps vmapped over environments (keys)
of one MDP; compile time is measured separately. Then the same-process comparison with gymnax's ``DeepSea-bsuite``
(size 20, 1024 environments, 500 steps, uniformly random actions drawn the same way for both, best of 5): jaxmdp's
DeepSea of the same size (episodic, its own auto-reset) against gymnax's ``step`` (auto-reset included, as it
renders a size x size observation). gymnax is the optional ``bench`` extra; without it that part is skipped.
Prints the tables and writes ``docs/benchmarks/bench_env.md`` (with the command) and ``results/bench_env.csv``.

    python scripts/bench_env.py                 # S~100 and S~1000 MDPs, 1/64/1024/8192 environments, gymnax
    python scripts/bench_env.py --quick         # smaller step counts
    python scripts/bench_env.py --gymnax-only   # only the gymnax comparison
"""

from __future__ import annotations

import argparse
import csv
import platform
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp

import jaxmdp
from jaxmdp.experiment import compilation

DEEPSEA_SIZE, DEEPSEA_ENVS, DEEPSEA_STEPS, DEEPSEA_REPEATS = 20, 1024, 500, 5


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


def lockstep_runner(reset, step, n_actions: int, n_envs: int, n_steps: int):
    """A jitted ``key -> sum of rewards`` of ``n_steps`` uniformly random actions in ``n_envs`` environments; the key
    handling and the action draw (``jax.random.randint``) are the same whatever ``reset``/``step`` are."""

    def run(key):
        k_reset, k_run = jax.random.split(key)
        _, states = jax.vmap(reset)(jax.random.split(k_reset, n_envs))

        def body(carry, k):
            states, total = carry
            k_act, k_step = jax.random.split(k)
            actions = jax.random.randint(k_act, (n_envs,), 0, n_actions)
            _, states, r, *_ = jax.vmap(step)(jax.random.split(k_step, n_envs), states, actions)
            return (states, total + jnp.sum(r)), None

        (_, total), _ = jax.lax.scan(body, (states, jnp.zeros(())), jax.random.split(k_run, n_steps))
        return total

    return jax.jit(run)


def time_runner(run, repeats: int) -> tuple[float, float]:
    """(compile seconds, best run seconds) of a jitted ``key -> scalar``."""
    key = jax.random.key(0)
    t0 = time.perf_counter()
    compiled = run.lower(key).compile()
    compile_s = time.perf_counter() - t0
    compiled(key).block_until_ready()
    best = float("inf")
    for i in range(repeats):
        t0 = time.perf_counter()
        compiled(jax.random.key(i + 1)).block_until_ready()
        best = min(best, time.perf_counter() - t0)
    return compile_s, best


def gymnax_comparison(n_envs: int, n_steps: int, repeats: int) -> list[dict] | None:
    """jaxmdp's and gymnax's DeepSea (size 20) in the same process; None without gymnax."""
    try:
        import gymnax
    except ImportError:
        print("gymnax is not installed (pip install -e .[bench]): skipping the DeepSea comparison", file=sys.stderr)
        return None
    env, params = gymnax.make("DeepSea-bsuite", size=DEEPSEA_SIZE)
    mdp = jaxmdp.make("DeepSea", episodic=True, seed=0, size=DEEPSEA_SIZE).strip()
    runners = {
        "jaxmdp.step (DeepSea)": lockstep_runner(
            lambda k: jaxmdp.reset(k, mdp), lambda k, s, a: jaxmdp.step(k, s, a, mdp), mdp.n_actions, n_envs, n_steps
        ),
        "gymnax DeepSea-bsuite": lockstep_runner(
            lambda k: env.reset(k, params), lambda k, s, a: env.step(k, s, a, params), 2, n_envs, n_steps
        ),
    }
    rows = []
    for name, run in runners.items():
        compile_s, run_s = time_runner(run, repeats)
        rows.append(dict(env=name, n_envs=n_envs, n_steps=n_steps, steps_per_s=n_envs * n_steps / run_s,
                         compile_s=compile_s, run_s=run_s))
        print(f"{name:24s} envs={n_envs}: {rows[-1]['steps_per_s'] / 1e6:8.3f} M steps/s "
              f"(run {run_s:.3f} s, compile {compile_s:.1f} s)", flush=True)
    ratio = rows[0]["steps_per_s"] / rows[1]["steps_per_s"]
    print(f"jaxmdp / gymnax: {ratio:.2f}x")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 64, 1024, 8192])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--gymnax-only", action="store_true", help="only the same-process comparison with gymnax")
    parser.add_argument("--out", type=Path, default=Path("results"), help="folder of the CSV")
    parser.add_argument("--doc", type=Path, default=Path("docs/benchmarks/bench_env.md"), help="the Markdown report")
    compilation.add_cache_flag(parser)
    args = parser.parse_args()
    folder, stats = compilation.setup_compilation(args.no_compile_cache)
    t_start = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    budget = 2_000_000 if args.quick else 20_000_000  # environment steps per measurement

    rows = []
    for name, mdp in [] if args.gymnax_only else benchmark_mdps():
        mdp = mdp.strip()
        for n in args.envs:
            n_steps = max(100, min(20_000, budget // n))
            sps, compile_s = measure(mdp, n, n_steps)
            rows.append(dict(mdp=name, n_states=mdp.n_states, n_envs=n, steps_per_s=sps, compile_s=compile_s))
            print(f"{name:22s} S={mdp.n_states:5d} envs={n:5d}: {sps / 1e6:8.3f} M steps/s (compile {compile_s:.1f} s)")
    versus = gymnax_comparison(DEEPSEA_ENVS, DEEPSEA_STEPS, DEEPSEA_REPEATS)

    if rows:
        with (args.out / "bench_env.csv").open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    report = compilation.time_report(time.perf_counter() - t_start, stats.snapshot(), folder)
    print(report)
    command = " ".join(["python", "scripts/bench_env.py", *sys.argv[1:]])
    lines = [
        "# Environment throughput (random actions)",
        "",
        f"`{command}`: jax {jax.__version__}, backend {jax.default_backend()}, "
        f"{platform.processor() or platform.machine()}; whole script: {report}.",
    ]
    if rows:
        lines += [
            "",
            "| MDP | S | parallel envs | M steps/s | compile s |",
            "|---|---|---|---|---|",
        ]
        lines += [
            f"| {r['mdp']} | {r['n_states']} | {r['n_envs']} | {r['steps_per_s'] / 1e6:.3f} | {r['compile_s']:.2f} |"
            for r in rows
        ]
    if versus:
        lines += [
            "",
            "## Against gymnax's DeepSea-bsuite (same process)",
            "",
            f"DeepSea size {DEEPSEA_SIZE}, {DEEPSEA_ENVS} environments, {DEEPSEA_STEPS} steps of uniformly random "
            f"actions (the same draw for both), best of {DEEPSEA_REPEATS} runs; gymnax's step also renders its "
            "size x size observation.",
            "",
            "| environment | M steps/s | run s | compile s |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {r['env']} | {r['steps_per_s'] / 1e6:.3f} | {r['run_s']:.3f} | {r['compile_s']:.2f} |" for r in versus
        ]
        lines += ["", f"jaxmdp / gymnax: **{versus[0]['steps_per_s'] / versus[1]['steps_per_s']:.2f}x**"]
    args.doc.parent.mkdir(parents=True, exist_ok=True)
    args.doc.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.doc}")


if __name__ == "__main__":
    main()
