"""Benchmark: random-action environment steps per second, for 1 to 8192 parallel environments, and against gymnax.

Each measurement is one jitted ``lax.scan`` of ``reset``-free random-action steps vmapped over environments (keys)
of one MDP; compile time is measured separately. Then the same-process comparison with gymnax's ``DeepSea-bsuite``
(size 20, 1024 environments, 500 steps, uniformly random actions drawn the same way for both, best of 5): jaxmdp's
DeepSea of the same size (episodic, its own auto-reset) against gymnax's ``step`` (auto-reset included, as it
renders a size x size observation). gymnax is the optional ``bench`` extra; without it that part is skipped.
Writes the tables to ``results/benchmarks/bench_env.md`` (``--update-docs``: also docs/performance.md) and the
measurements to ``results/benchmarks/bench_env.csv``.

    python benchmarks/bench_env.py                 # S~100 and S~1000 MDPs, 1/64/1024/8192 environments, gymnax
    python benchmarks/bench_env.py --quick         # smaller step counts
    python benchmarks/bench_env.py --gymnax-only   # only the gymnax comparison
    python benchmarks/bench_env.py --families      # gymnax, then every family's step against the old step
    python benchmarks/bench_env.py --smoke         # a tiny MDP, 1 and 4 environments, 100 steps

``--families`` (after the gymnax comparison, without the size sweep) times, in the same process, the step of every
family's quick-test MDPs (``docs/benchmark.md §3``, both settings, and MiniGridDoorKey; its Beta sampler
:func:`jaxmdp.sampling.beta_shared.sample_beta_shared`) against the same step with the previous Beta sampler
:func:`jaxmdp.sampling.beta_sampling.sample_beta` (:func:`step_with_old_sampler`) and against the old step, the dense
formulation that ``jaxmdp.step`` replaced
(its code is kept here as :func:`old_step`: a reset state drawn by a cumulative sum over the whole ``P0`` at every
episodic step, the successor by a cumulative sum over the successor list, every draw compiled), at 1024 environments
and 500 steps of random actions (the same draw for all), best of 5 interleaved runs; it writes the table into the
tables and ``results/benchmarks/bench_env_families.csv``.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from collections.abc import Sequence

import jax
import jax.numpy as jnp

import jaxmdp
from jaxmdp.env import EnvState
import jaxmdp.env
from jaxmdp.experiment import compilation
from jaxmdp.sampling.beta_sampling import sample_beta

import _common

NAME = "bench_env"

DEEPSEA_SIZE, DEEPSEA_ENVS, DEEPSEA_STEPS, DEEPSEA_REPEATS = 20, 1024, 500, 5
FAMILY_ENVS, FAMILY_STEPS, FAMILY_REPEATS = 1024, 500, 5
# MiniGridDoorKey has no quick-test MDP; the smallest of its benchmark sizes.
DOORKEY = dict(size=5, make_reward_stochastic=True, p_lazy=0.05, p_rand=0.05)


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


def step_with_old_sampler(key: jax.Array, state: EnvState, action: jax.Array, mdp: jaxmdp.MDP):
    """``jaxmdp.step`` with the previous Beta sampler :func:`~jaxmdp.sampling.beta_sampling.sample_beta` swapped in
    while the step is traced (the step before the shared sampler of :mod:`jaxmdp.sampling.beta_shared`)."""
    current = jaxmdp.env.sample_beta_shared
    jaxmdp.env.sample_beta_shared = sample_beta
    try:
        return jaxmdp.step(key, state, action, mdp)
    finally:
        jaxmdp.env.sample_beta_shared = current


def old_step(key: jax.Array, state: EnvState, action: jax.Array, mdp: jaxmdp.MDP):
    """The step before the ``O(K)`` one (commit ae021f5), kept as the baseline of ``--families``: the same key use and
    distributions, with a reset state drawn by an ``O(S)`` cumulative sum over ``P0`` at every episodic step whether or
    not the episode ends, the successor by a cumulative sum over the successor list, and the reward draw compiled
    whenever any reward is a Beta."""
    k_reward, k_uniform = jax.random.split(key)
    u_next, u_reset = jax.random.uniform(k_uniform, (2,), dtype=mdp.dtype)
    action = jnp.asarray(action, jnp.int32)
    cdf = jnp.cumsum(mdp.succ_p[state.state, action])
    k = jnp.minimum(jnp.sum(cdf <= u_next * cdf[-1]), cdf.shape[-1] - 1)
    s_next = mdp.succ[state.state, action, k].astype(jnp.int32)
    mean = mdp.reward_mean[state.state, action, s_next]
    reward = mean
    if mdp.stochastic_rewards:
        conc = mdp.reward_conc[state.state, action, s_next]
        stochastic = conc > 0
        alpha = jnp.where(stochastic, mean * conc, 1.0)
        beta = jnp.where(stochastic, (1.0 - mean) * conc, 1.0)
        reward = jnp.where(stochastic, sample_beta(k_reward, alpha, beta, dtype=mdp.dtype), mean)
    h_next = state.h + 1
    terminated = (h_next >= mdp.horizon) if mdp.episodic else jnp.zeros((), bool)
    if mdp.episodic:
        p0 = jnp.cumsum(mdp.P0)
        s_reset = jnp.minimum(jnp.sum(p0 <= u_reset * p0[-1]), mdp.n_states - 1).astype(jnp.int32)
    else:
        s_reset = state.state
    h = jnp.where(terminated, 0, h_next).astype(jnp.int32)
    new_state = EnvState(state=jnp.where(terminated, s_reset, s_next), h=h)
    return new_state.state, new_state, reward, terminated, jnp.zeros((), bool), {}


def family_mdps() -> list[tuple[str, jaxmdp.MDP]]:
    """Every family's quick-test MDPs (both settings; ``hardness.benchmark.sets``) and MiniGridDoorKey's, seed 0."""
    from hardness.benchmark import sets

    out = []
    for set_name in sets.QUICK_SETS:
        for inst in sets.instances(set_name):
            out.append((f"{inst.family} ({'episodic' if inst.episodic else 'continuous'})", inst.build(0)))
    if "MiniGridDoorKey" in jaxmdp.families():
        for episodic in (True, False):
            out.append((f"MiniGridDoorKey ({'episodic' if episodic else 'continuous'})",
                        jaxmdp.make("MiniGridDoorKey", episodic=episodic, seed=0, **DOORKEY)))
    return out


def families_comparison(n_envs: int, n_steps: int, repeats: int) -> list[dict]:
    """``jaxmdp.step`` against :func:`step_with_old_sampler` and :func:`old_step` on every family's MDPs, same
    process, interleaved runs, best of each."""
    rows = []
    for name, mdp in family_mdps():
        mdp = mdp.strip()
        steps = (("new", jaxmdp.step), ("old_sampler", step_with_old_sampler), ("old", old_step))
        runners = {
            which: lockstep_runner(lambda k: jaxmdp.reset(k, mdp), lambda k, s, a, f=f: f(k, s, a, mdp),
                                   mdp.n_actions, n_envs, n_steps)
            for which, f in steps
        }
        compiled, compile_s, best = {}, {}, {}
        for which, run in runners.items():
            t0 = time.perf_counter()
            compiled[which] = run.lower(jax.random.key(0)).compile()
            compile_s[which] = time.perf_counter() - t0
            compiled[which](jax.random.key(0)).block_until_ready()
            best[which] = float("inf")
        for i in range(repeats):
            for which, run in compiled.items():
                t0 = time.perf_counter()
                run(jax.random.key(i + 1)).block_until_ready()
                best[which] = min(best[which], time.perf_counter() - t0)
        new, old_sampler, old = (n_envs * n_steps / best[w] for w in ("new", "old_sampler", "old"))
        rows.append(dict(mdp=name, n_states=mdp.n_states, K=mdp.succ.shape[-1], beta=mdp.stochastic_rewards,
                         n_envs=n_envs, n_steps=n_steps, new_steps_per_s=new, old_sampler_steps_per_s=old_sampler,
                         old_steps_per_s=old, sampler_speedup=new / old_sampler, speedup=new / old,
                         compile_s=compile_s["new"]))
        print(f"{name:30s} S={mdp.n_states:4d}: step {new / 1e6:7.2f} M/s, with the old sampler "
              f"{old_sampler / 1e6:7.2f} M/s (step {new / old_sampler:.2f}x), old step {old / 1e6:7.2f} M/s "
              f"(step {new / old:.2f}x)", flush=True)
    return rows


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


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 64, 1024, 8192])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--gymnax-only", action="store_true", help="only the same-process comparison with gymnax")
    parser.add_argument("--families", action="store_true",
                        help="the gymnax comparison and every family's step against the old step, same process, "
                             "without the size sweep (module docstring)")
    _common.add_common_args(parser)
    args = parser.parse_args(argv)
    global DEEPSEA_ENVS, DEEPSEA_STEPS, DEEPSEA_REPEATS
    if args.smoke:
        args.envs, args.gymnax_only, args.families = [1, 4], False, False
        DEEPSEA_ENVS, DEEPSEA_STEPS, DEEPSEA_REPEATS = 4, 100, 1
    folder, stats = compilation.setup_compilation(args.no_compile_cache)
    t_start = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    budget = 400 if args.smoke else 2_000_000 if args.quick else 20_000_000  # environment steps per measurement
    mdps = [("RiverSwim size 5", jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5))] if args.smoke else \
        benchmark_mdps()

    rows = []
    only = args.gymnax_only or args.families
    for name, mdp in [] if only else mdps:
        mdp = mdp.strip()
        for n in args.envs:
            n_steps = max(100, min(20_000, budget // n))
            if args.smoke:
                n_steps = 100
            sps, compile_s = measure(mdp, n, n_steps)
            rows.append(dict(mdp=name, n_states=mdp.n_states, n_envs=n, steps_per_s=sps, compile_s=compile_s))
            print(f"{name:22s} S={mdp.n_states:5d} envs={n:5d}: {sps / 1e6:8.3f} M steps/s (compile {compile_s:.1f} s)")
    versus = gymnax_comparison(DEEPSEA_ENVS, DEEPSEA_STEPS, DEEPSEA_REPEATS)
    families = families_comparison(FAMILY_ENVS, FAMILY_STEPS, FAMILY_REPEATS) if args.families else []
    if families:
        with (args.out / "bench_env_families.csv").open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(families[0]))
            w.writeheader()
            w.writerows(families)

    if rows:
        with (args.out / "bench_env.csv").open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    report = compilation.time_report(time.perf_counter() - t_start, stats.snapshot(), folder)
    print(report, file=sys.stderr)
    lines = [f"Random-action steps of `jaxmdp.step`, vmapped over environments in one jitted `lax.scan`; whole "
             f"benchmark: {report}."]
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
            "Against gymnax's DeepSea-bsuite (same process):",
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
    if families:
        lines += [
            "",
            "Every family against the old step (same process):",
            "",
            f"The quick-test MDPs of every family (seed 0) and MiniGridDoorKey, {FAMILY_ENVS} environments, "
            f"{FAMILY_STEPS} steps of uniformly random actions (the same draw for all), best of {FAMILY_REPEATS} "
            "interleaved runs: `jaxmdp.step` (Beta sampler `jaxmdp.sampling.beta_shared`) against the same step "
            "with the previous Beta sampler `jaxmdp.sampling.beta_sampling.sample_beta` (`step_with_old_sampler` in "
            "the benchmark) and against the dense step it replaced (`old_step`, with the previous sampler). Beta: "
            "whether the MDP has Beta rewards (else no draw is compiled).",
            "",
            "| MDP | S | K | Beta | step, M steps/s | with the old sampler, M steps/s | step / old sampler | "
            "old step, M steps/s | step / old step | compile s |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        lines += [
            f"| {r['mdp']} | {r['n_states']} | {r['K']} | {'yes' if r['beta'] else 'no'} | "
            f"{r['new_steps_per_s'] / 1e6:.2f} | {r['old_sampler_steps_per_s'] / 1e6:.2f} | "
            f"{r['sampler_speedup']:.2f}x | "
            f"{r['old_steps_per_s'] / 1e6:.2f} | {r['speedup']:.2f}x | {r['compile_s']:.2f} |" for r in families
        ]
    elif not only:
        lines += ["", "gymnax is not installed (`pip install -e .[bench]`): no comparison."]
    _common.publish(NAME, "Environment step", lines, args, argv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
