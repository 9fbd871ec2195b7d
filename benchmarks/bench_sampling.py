"""Speed of the Gamma/Beta sampler ``jaxmdp.sampling.beta_sampling`` against ``jax.random`` (``dirichlet``, ``beta``,
``loggamma``), both in one process, interleaved, best of ``--reps`` (other processes share the machine: read the
ratios). Four measurements:

1. Dirichlet posterior draws, ns per Gamma entry: ``vmap`` over members of ``agents.posteriors.dirichlet_sample``
   against ``jax.random.dirichlet`` (log-Gammas then a softmax, as ours) on ``[S, A, S]`` concentrations
   ``1/S + counts`` (counts ~ Poisson(0.3): mostly shapes below one, the boosted and slowest case).
2. Beta rewards, ns per draw: ``vmap`` of ``sample_beta`` against ``jax.random.beta`` over 4096 members, shapes
   uniform on (0.05, 5).
3. PSRL continuous's candidate states, ns per index: ``vmap`` over 4 members of ``[psi, S, A] = [60, 784, 3]``
   uniform integers below each member's traced number of real states (770-784), ``jax.random.randint`` and its
   bit-for-bit written-out copy ``fused_random.randint`` against ``fused_random.uniform_index`` (what a plan draws).
4. PSRL episodic agent-steps per second on MiniGridEmpty size 5 (S = 100, A = 3, H = 13), 64 seeds, through
   ``jaxmdp.experiment.runner`` (indicators every 100 steps): the registered agent against the same agent whose
   ``plan`` draws its posteriors with ``jax.random.loggamma`` (``psrl_episodic.plan``'s ``log_gamma`` argument).
   The MDP's rewards are deterministic, so the environment draws no Beta rewards. One host device per core, as
   ``benchmarks/bench_agents.py``.

    python benchmarks/bench_sampling.py [--reps 3] [--psrl-steps 520] [--update-docs]
    python benchmarks/bench_sampling.py --smoke
"""

from __future__ import annotations

if __name__ == "__main__":
    from jaxmdp.experiment.devices import use_every_core

    use_every_core()  # before any JAX computation: one lockstep loop per core (the runner shards over host devices)

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import functools  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import agents  # noqa: E402
import agents.posteriors as posteriors  # noqa: E402
import jaxmdp  # noqa: E402
from jaxmdp.experiment import compilation  # noqa: E402
from agents import psrl_episodic  # noqa: E402
from jaxmdp.experiment import runner  # noqa: E402
from jaxmdp.sampling import beta_sampling, fused_random  # noqa: E402

import _common  # noqa: E402

NAME = "bench_sampling"


def jax_log_gamma(key, a):
    """``jax.random.loggamma`` as a ``log_gamma`` sampler of ``agents.posteriors`` (``a``'s dtype)."""
    return jax.random.loggamma(key, a, dtype=a.dtype)


def interleaved(fns: dict, args: tuple, reps: int) -> dict:
    """Best-of-``reps`` wall and CPU seconds of each function, the functions called in turn."""
    best = {k: [np.inf, np.inf] for k in fns}
    for f in fns.values():
        jax.block_until_ready(f(*args))  # compile
    for _ in range(reps):
        for k, f in fns.items():
            t, c = time.perf_counter(), time.process_time()
            jax.block_until_ready(f(*args))
            best[k][0] = min(best[k][0], time.perf_counter() - t)
            best[k][1] = min(best[k][1], time.process_time() - c)
    return best


def dirichlet_draws(members: int, S: int, A: int, reps: int) -> dict:
    keys = jax.random.split(jax.random.key(0), members)
    counts = jax.random.poisson(jax.random.key(1), 0.3, (members, S, A, S))
    alpha = (1.0 / S + counts).astype(jnp.float32)
    fns = {
        "jax": jax.jit(jax.vmap(jax.random.dirichlet)),
        "new": jax.jit(jax.vmap(posteriors.dirichlet_sample)),
    }
    best = interleaved(fns, (keys, alpha), reps)
    n = alpha.size
    return dict(shape=f"[{members}, {S}, {A}, {S}]", entries=n, below_one=float(jnp.mean(alpha < 1.0)),
                **{f"{k}_{m}": v[i] / n * 1e9 for k, v in best.items() for i, m in enumerate(("wall", "cpu"))})


def beta_draws(members: int, reps: int) -> dict:
    keys = jax.random.split(jax.random.key(2), members)
    a = jax.random.uniform(jax.random.key(3), (members,), minval=0.05, maxval=5.0)
    b = jax.random.uniform(jax.random.key(4), (members,), minval=0.05, maxval=5.0)
    fns = {"jax": jax.jit(jax.vmap(jax.random.beta)), "new": jax.jit(jax.vmap(beta_sampling.sample_beta))}
    best = interleaved(fns, (keys, a, b), reps * 20)
    return dict(members=members, **{f"{k}_{m}": v[i] / members * 1e9 for k, v in best.items()
                                    for i, m in enumerate(("wall", "cpu"))})


def index_draws(members: int, shape: tuple[int, int, int], reps: int) -> dict:
    keys = jax.random.split(jax.random.key(5), members)
    spans = jnp.asarray(shape[1] - np.arange(members) * 14 // max(members - 1, 1), jnp.int32)
    fns = {
        "jax": jax.jit(jax.vmap(lambda k, n: jax.random.randint(k, shape, 0, n))),
        "fused": jax.jit(jax.vmap(lambda k, n: fused_random.randint(k, shape, 0, n))),
        "new": jax.jit(jax.vmap(lambda k, n: fused_random.uniform_index(k, shape, n))),
    }
    best = interleaved(fns, (keys, spans), reps * 20)
    n = members * int(np.prod(shape))
    return dict(shape=f"{members} x {list(shape)}", **{f"{k}_{m}": v[i] / n * 1e9 for k, v in best.items()
                                                      for i, m in enumerate(("wall", "cpu"))})


def psrl_steps(seeds: int, steps: int, reps: int) -> dict:
    mdp = jaxmdp.make("MiniGridEmpty", episodic=True, seed=0, size=5)
    assert not mdp.stochastic_rewards  # so the environment's Beta sampler plays no part
    base = agents.get("psrl_episodic")
    jax_plan = functools.partial(psrl_episodic.plan, log_gamma=jax_log_gamma)
    versions = {"jax": dataclasses.replace(base, name="psrl_episodic[jax.random]", plan=jax_plan), "new": base}
    grid = runner.product([mdp], [base.default_hparams], seeds=range(seeds))
    best, compile_s = {k: np.inf for k in versions}, {}
    for rep in range(reps + 1):  # the first run of each compiles
        for k, agent in versions.items():
            res = runner.run(agent, grid, steps, log_period=100, n_records=5)
            if rep == 0:
                compile_s[k] = res.compile_s
            best[k] = min(best[k], res.run_s)
            print(f"  psrl {k}: {seeds * steps / res.run_s:,.0f} agent-steps/s", flush=True)
    return dict(S=mdp.n_states, seeds=seeds, steps=steps,
                **{f"{k}_steps_per_s": seeds * steps / v for k, v in best.items()},
                **{f"{k}_compile_s": v for k, v in compile_s.items()})


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=3, help="timed repetitions of each measurement (best is kept)")
    ap.add_argument("--psrl-reps", type=int, default=1)
    ap.add_argument("--psrl-steps", type=int, default=520, help="agent steps per seed (H = 13: 40 episodes)")
    _common.add_common_args(ap)
    args = ap.parse_args(argv)
    if args.smoke:
        args.reps, args.psrl_reps, args.psrl_steps = 1, 1, 20
    cache_folder, compile_stats = compilation.setup_compilation(args.no_compile_cache)
    t_script = time.perf_counter()

    draws = [dirichlet_draws(2, 5, 2, args.reps) if args.smoke else dirichlet_draws(64, 100, 4, args.reps)]
    for d in draws:
        print(f"Dirichlet {d['shape']}: jax {d['jax_wall']:.1f} ns, new {d['new_wall']:.1f} ns per entry "
              f"({d['jax_wall'] / d['new_wall']:.1f}x)", flush=True)
    beta = beta_draws(16 if args.smoke else 4096, args.reps)
    print(f"Beta x{beta['members']}: jax {beta['jax_wall']:.0f} ns, new {beta['new_wall']:.0f} ns per draw "
          f"({beta['jax_wall'] / beta['new_wall']:.1f}x)", flush=True)
    index = index_draws(2, (2, 9, 3), args.reps) if args.smoke else index_draws(4, (60, 784, 3), args.reps)
    print(f"Candidate states {index['shape']}: jax.random.randint {index['jax_wall']:.2f} ns, fused randint "
          f"{index['fused_wall']:.2f} ns, uniform_index {index['new_wall']:.2f} ns per index", flush=True)
    psrl = None  # smoke size: the runner's PSRL programs alone take minutes to compile, so they are left out
    if not args.smoke:
        psrl = psrl_steps(64, args.psrl_steps, args.psrl_reps)
        print(f"PSRL episodic: jax {psrl['jax_steps_per_s']:,.0f}, new {psrl['new_steps_per_s']:,.0f} agent-steps/s "
              f"({psrl['new_steps_per_s'] / psrl['jax_steps_per_s']:.1f}x)", flush=True)
    _common.publish(NAME, "Sampling: jaxmdp.sampling against jax.random", body(draws, beta, index, psrl, args),
                    args, argv)
    print(compilation.time_report(time.perf_counter() - t_script, compile_stats.snapshot(), cache_folder),
          file=sys.stderr)
    return 0


def body(draws: list[dict], beta: dict, index: dict, psrl: dict | None, args) -> list[str]:
    """The table's lines: Dirichlet and Beta draws, then candidate states, then PSRL in the runner."""
    lines = [
        f"`jax.random` and ours (`jaxmdp.sampling.beta_sampling`) timed in one process, interleaved, best of "
        f"{args.reps} (PSRL: best of {args.psrl_reps}); read the ratios. Wall ns, then CPU ns summed over threads.",
        "",
        "| measurement | jax wall | ours wall | speed-up | jax CPU | ours CPU | speed-up |",
        "|---|---|---|---|---|---|---|",
    ]
    for d in draws:
        lines.append(
            f"| Dirichlet posterior, ns per Gamma entry: {d['shape']}, {d['below_one']:.0%} shapes < 1 | "
            f"{d['jax_wall']:.1f} | {d['new_wall']:.1f} | {d['jax_wall'] / d['new_wall']:.1f}x | {d['jax_cpu']:.1f} | "
            f"{d['new_cpu']:.1f} | {d['jax_cpu'] / d['new_cpu']:.1f}x |")
    lines.append(
        f"| Beta rewards, ns per draw: {beta['members']} members, shapes uniform on (0.05, 5) | "
        f"{beta['jax_wall']:.0f} | {beta['new_wall']:.0f} | {beta['jax_wall'] / beta['new_wall']:.1f}x | "
        f"{beta['jax_cpu']:.0f} | {beta['new_cpu']:.0f} | {beta['jax_cpu'] / beta['new_cpu']:.1f}x |")
    lines += [
        "",
        f"PSRL continuous's candidate states, ns per index ({index['shape']}, a traced span per member), best of "
        f"{args.reps * 20}: `jax.random.randint`, its written-out copy `fused_random.randint` (the same integers) "
        "and `fused_random.uniform_index` (one hash and a multiply-shift an index; what a plan draws).",
        "",
        "| sampler | wall ns |",  # a call takes under a millisecond: too short for the CPU clock's ticks
        "|---|---|",
        *(f"| {name} | {index[k + '_wall']:.2f} |" for k, name in
          (("jax", "jax.random.randint"), ("fused", "fused_random.randint"), ("new", "fused_random.uniform_index"))),
    ]
    if psrl is None:
        return lines
    lines += [
        "",
        f"PSRL episodic in the runner: MiniGridEmpty (S = {psrl['S']}), {psrl['seeds']} seeds, {psrl['steps']} steps, "
        "indicators every 100 steps, one host device per core; jax: the agent's posteriors drawn with "
        "`jax.random.loggamma` (deterministic rewards: no Beta draws).",
        "",
        "| sampler | agent-steps/s | compile s |",
        "|---|---|---|",
        f"| jax.random | {psrl['jax_steps_per_s']:,.0f} | {psrl['jax_compile_s']:.1f} |",
        f"| ours | {psrl['new_steps_per_s']:,.0f} | {psrl['new_compile_s']:.1f} |",
    ]
    return lines


if __name__ == "__main__":
    sys.exit(main())
