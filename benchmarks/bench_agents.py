"""Throughput of every registered agent in the lockstep runner: agent-steps per second at 1, 64 and 1024 seeds.

Each measurement runs ``runner.run`` (environment + agent + exact indicators every 100 steps, as the reference's
benchmark) for ``--steps`` steps per seed on the benchmark MDPs of ``docs/benchmark.md §10``: RiverSwim (continuous
communicating ``prms_0``, episodic communicating ``prms_0``), and Taxi / MiniGridEmpty when those families are
registered. Compilation is timed separately. The reference's single-run throughput is printed beside ours.

A profile at the largest seed count splits the time of each agent into environment (the random agent, no
indicators), agent (the agent, no indicators, minus the environment) and indicators (the rest).

The CPU backend runs one lockstep loop per device, so the script exposes one host device per core
(``XLA_FLAGS=--xla_force_host_platform_device_count``) unless ``XLA_FLAGS`` already sets it; the runner shards the
members over them. Writes ``results/benchmarks/bench_agents.md`` (``--update-docs``: also docs/performance.md) and
``results/benchmarks/bench_agents.csv``. A seed count whose predicted run time exceeds ``--max-seconds`` is skipped
(and marked so in the table).

Deep agents (``agent.observation == "emission"``) run on the ``state_info`` BlockMDP of RiverSwim at ``--deep-seeds``
(1, 16, 64), and beside DQN the script times the baseline a user would otherwise pick: bsuite's own JAX DQN
(``bsuite.baselines.jax.dqn``, one seed, its per-step Python loop) on the same MDP and observations with the same
network, batch, replay and periods (``pip install -e ".[bench]"``; skipped with a note when bsuite is missing).

``--ratio`` measures instead each tabular agent's cost per step against the random agent's of its setting (the
issue's "at most 1.5x"), back to back in one process so that a shared machine's load weighs on both: for every
benchmark MDP at the largest seed count, the random agent and the agent, each with indicators every 100 steps and
without, the four runs interleaved ``--repeats`` times after a compiling run, best of each. It reports the cost ratio
and the wall ns per agent-step of environment, agent and indicators (``results/benchmarks/bench_agents_ratio.md``,
``.csv``).

With ``--ratio``, each deep agent other than DQN is measured the same way against DQN of its setting, on the deep
agents' BlockMDP at the largest ``--deep-seeds`` count: the two runs (indicators every 100 steps) interleaved
``--repeats`` times after a compiling run each, best of each (``results/benchmarks/bench_agents_deep_ratio.md``).

``--mdps N`` spreads the tabular agents' members over N MDPs of each benchmark MDP's family and parameters (seeds
``0 .. N-1``): a stack of MDPs, as every batch of the benchmark is (one per size bucket), where one MDP (the default)
lets every member read the same tables.

    python benchmarks/bench_agents.py [--quick] [--steps N] [--seeds 1,64,1024] [--deep-seeds 1,16,64] \
        [--agents a,b] [--mdps N] [--repeats R] [--ratio] [--update-docs]
    python benchmarks/bench_agents.py --quick --ratio --seeds 1024 --repeats 3 \
        --agents q_learning_episodic,q_learning_continuous         # each agent's cost against the random agent's
    python benchmarks/bench_agents.py --ratio --quick --steps 1000 --deep-seeds 16 --repeats 3 \
        --agents boot_dqn_continuous                                   # BootDQN's cost against DQN's
    python benchmarks/bench_agents.py --smoke
"""

from __future__ import annotations

if __name__ == "__main__":
    from jaxmdp.experiment.devices import use_every_core

    use_every_core()  # before any JAX computation: one lockstep loop per core (the runner shards over host devices)

import argparse  # noqa: E402
import csv  # noqa: E402
import math  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402

import jax  # noqa: E402

import agents  # noqa: E402
import jaxmdp  # noqa: E402
from jaxmdp.experiment import compilation  # noqa: E402
from jaxmdp.experiment import runner  # noqa: E402

import _common  # noqa: E402

NAME = "bench_agents"

# The benchmark MDPs of docs/benchmark.md §10 (docs/benchmark.md §3 scopes), keyed by (family, episodic).
BENCH_MDPS = {
    ("RiverSwim", False): dict(size=25, p_lazy=0.1, make_reward_stochastic=True, randomize_actions=False),
    ("RiverSwim", True): dict(size=25, p_lazy=0.05, make_reward_stochastic=True, randomize_actions=False),
    ("Taxi", False): dict(size=4, length=1, width=1, space=1, n_locations=3, p_lazy=0.01,
                          make_reward_stochastic=True, randomize_actions=False),
    ("Taxi", True): dict(size=4, length=1, width=1, space=1, n_locations=3, p_lazy=0.01,
                         make_reward_stochastic=True, randomize_actions=False),
    ("MiniGridEmpty", False): dict(size=8, p_lazy=0.3, n_starting_states=3, make_reward_stochastic=False,
                                   randomize_actions=False),
    ("MiniGridEmpty", True): dict(size=6, n_starting_states=3, make_reward_stochastic=True, randomize_actions=False),
}

# The reference's steps per second (one run, 20 000 steps, indicators every 100 steps; docs/benchmark.md §10).
REFERENCE = {
    ("q_learning_continuous", "RiverSwim"): "35.9k",
    ("q_learning_continuous", "Taxi"): "21.2k",
    ("q_learning_continuous", "MiniGridEmpty"): "23.5-25.3k",
    ("ucrl2", "RiverSwim"): "5.7k",
    ("ucrl2", "Taxi"): "1.9k",
    ("ucrl2", "MiniGridEmpty"): "1.9k",
    ("psrl_continuous", "RiverSwim"): "9.4k",
    ("psrl_continuous", "Taxi"): "27",
    ("psrl_continuous", "MiniGridEmpty"): "~2.6",
    ("q_learning_episodic", "RiverSwim"): "17.4k",
    ("q_learning_episodic", "Taxi"): "14.2-14.6k",
    ("q_learning_episodic", "MiniGridEmpty"): "18.2-20.2k",
    ("psrl_episodic", "RiverSwim"): "18.5k",
    ("psrl_episodic", "Taxi"): "3.4k",
    ("psrl_episodic", "MiniGridEmpty"): "2.9k",
}
NO_INDICATORS = 2**30  # a log period longer than any run: only the final log happens


def bench_mdps(family: str, episodic: bool, n_mdps: int) -> list:
    """``n_mdps`` MDPs of the benchmark MDP's family and parameters (:data:`BENCH_MDPS`), seeds ``0 .. n_mdps - 1``:
    with more than one, a grid is a stack of MDPs, as every batch of the benchmark is (one per size bucket)."""
    return [jaxmdp.make(family, episodic=episodic, seed=i, **BENCH_MDPS[(family, episodic)]) for i in range(n_mdps)]


def grid_of(agent, mdps: list, members: int):
    """``members`` members spread evenly over ``mdps`` (``members / len(mdps)`` seeds each)."""
    if members % len(mdps):
        raise ValueError(f"--seeds ({members}) must be a multiple of --mdps ({len(mdps)})")
    return runner.product(mdps, [agent.default_hparams], seeds=range(members // len(mdps)))


def measure(agent, mdps: list, seeds: int, steps: int, repeats: int, log_period: int = 100, shards=None) -> dict:
    """Best-of-``repeats`` wall and CPU time per agent-step of ``seeds`` members over ``mdps``; the first call's
    compile time."""
    g = grid_of(agent, mdps, seeds)
    first = runner.run(agent, g, steps, log_period=log_period, n_records=10, shards=shards)
    walls, cpus, res = [first.run_s], [], first
    for _ in range(repeats):
        c0 = time.process_time()
        res = runner.run(agent, g, steps, log_period=log_period, n_records=10, shards=shards)
        cpus.append(time.process_time() - c0)
        walls.append(res.run_s)
    n = steps * seeds
    return {
        "compile_s": first.compile_s,
        "steps_per_s": n / min(walls),
        "cpu_ns_per_step": 1e9 * min(cpus) / n if cpus else float("nan"),
        "regret": float(res.column("normalized_cumulative_regret")[-1].mean() / steps),
    }


# ---------------------------------------------------------------------------------------------------------------
# The baseline a user would otherwise pick: bsuite's own JAX DQN (bsuite/baselines/jax/dqn), one seed, its per-step
# Python loop, on the same MDP and emission table, with the same network sizes, batch and replay settings.
# ---------------------------------------------------------------------------------------------------------------


def bsuite_dqn_steps_per_s(mdp, table, hparams, steps: int, seed: int = 0) -> dict | None:
    """Steps per second of bsuite's JAX DQN agent on ``mdp`` observed through ``table`` (noiseless emission rows);
    ``None`` when bsuite, dm-haiku or rlax are not installed (``pip install -e ".[bench]"``)."""
    try:
        import dm_env
        import haiku as hk
        import optax
        from bsuite.baselines.jax.dqn.agent import DQN
        from dm_env import specs
    except ImportError:
        return None
    import numpy as np

    T = np.asarray(mdp.T, np.float64)
    T /= T.sum(-1, keepdims=True)  # float32 rows, renormalised for numpy's sampler
    R = np.asarray(mdp.reward_mean, np.float64)  # mean reward of each transition [S, A, S']
    P0 = np.asarray(mdp.P0, np.float64)
    P0 /= P0.sum()
    table = np.asarray(table, np.float32)
    episodic, H = mdp.episodic, int(mdp.horizon) if mdp.episodic else 0

    class TabularEnv(dm_env.Environment):
        """The MDP as a dm_env environment with numpy sampling (cheap next to the agent's per-step cost)."""

        def __init__(self):
            self.rng = np.random.default_rng(seed)

        def _obs(self):
            return table[self.h, self.s] if episodic else table[self.s]

        def reset(self):
            self.s, self.h = int(self.rng.choice(len(P0), p=P0)), 0
            return dm_env.restart(self._obs())

        def step(self, action):
            s2 = int(self.rng.choice(T.shape[2], p=T[self.s, action]))
            r, self.s, self.h = float(R[self.s, action, s2]), s2, self.h + 1
            if episodic and self.h >= H:
                return dm_env.termination(r, np.zeros_like(table[0, 0]))  # past the end: all zeros, as the reference
            return dm_env.transition(r, self._obs())

        def observation_spec(self):
            return specs.Array(table.shape[2:] if episodic else table.shape[1:], np.float32)

        def action_spec(self):
            return specs.DiscreteArray(T.shape[1])

    env = TabularEnv()
    width, depth = int(hparams.network_width), int(hparams.network_depth)

    def network(x):
        return hk.nets.MLP([width] * depth + [T.shape[1]])(hk.Flatten()(x))

    np.random.seed(seed)  # bsuite's agent draws its exploration from numpy's global generator
    agent = DQN(
        obs_spec=env.observation_spec(), action_spec=env.action_spec(), network=network,
        optimizer=optax.adam(float(hparams.learning_rate)), batch_size=int(hparams.batch_size),
        epsilon=float(hparams.epsilon), rng=hk.PRNGSequence(seed), discount=float(hparams.discount),
        replay_capacity=int(hparams.replay_capacity), min_replay_size=int(hparams.min_replay),
        sgd_period=int(hparams.sgd_period), target_update_period=int(hparams.target_update_period),
    )
    ts = env.reset()
    warm = min(steps // 4, 1000)  # past min_replay so every timed step includes its SGD, after jit compilation
    t0 = None
    for i in range(steps + warm):
        if i == warm:
            t0 = time.perf_counter()
        a = agent.select_action(ts)
        new_ts = env.step(a)
        agent.update(ts, a, new_ts)
        ts = env.reset() if new_ts.last() else new_ts
    return {"steps_per_s": steps / (time.perf_counter() - t0)}


def deep_mdp(episodic: bool):
    """The deep agents' benchmark MDP: RiverSwim of :data:`BENCH_MDPS` through the ``state_info`` emission."""
    return jaxmdp.block_mdp(bench_mdps("RiverSwim", episodic, 1)[0], "state_info")


def interleaved_ns(runs: dict, mdps: list, seeds: int, steps: int, repeats: int) -> dict:
    """Best wall ns per agent-step of each run ``name -> (agent, log_period)``, the runs interleaved ``repeats`` times
    after a compiling run each, so that a shared machine's load weighs on all of them alike."""
    grids = {k: grid_of(a, mdps, seeds) for k, (a, _) in runs.items()}
    go = lambda k: runner.run(runs[k][0], grids[k], steps, log_period=runs[k][1], n_records=10).run_s  # noqa: E731
    for k in runs:
        go(k)  # compiles
    best = {k: float("inf") for k in runs}
    for _ in range(repeats):
        for k in runs:
            best[k] = min(best[k], go(k))
    return {k: 1e9 * v / (steps * seeds) for k, v in best.items()}


def measure_ratio(agent, random_agent, mdps: list, seeds: int, steps: int, repeats: int) -> dict:
    """The agent's and the random agent's wall seconds per agent-step, with indicators every 100 steps and without,
    measured back to back in one process: the four runs interleaved ``repeats`` times after a compiling run each,
    best of each (a shared machine's load then weighs on all four alike)."""
    runs = {
        "random_env": (random_agent, NO_INDICATORS), "random": (random_agent, 100),
        "agent_bare": (agent, NO_INDICATORS), "agent": (agent, 100),
    }
    ns = interleaved_ns(runs, mdps, seeds, steps, repeats)
    return dict(
        random_steps_per_s=1e9 / ns["random"], agent_steps_per_s=1e9 / ns["agent"], ratio=ns["agent"] / ns["random"],
        env_ns=ns["random_env"], agent_ns=ns["agent_bare"] - ns["random_env"],
        indicators_ns=ns["agent"] - ns["agent_bare"], random_indicators_ns=ns["random"] - ns["random_env"],
    )


def main_ratio(args, names: list[str], families: list[str], argv: Sequence[str] | None = None) -> None:
    """``--ratio``: each tabular agent against the random agent of its setting on every benchmark MDP."""
    seeds = [int(s) for s in args.seeds.split(",")][-1]
    load0 = os.getloadavg()
    rows = []
    for name in names:
        agent = agents.get(name)
        if agent.observation != "state" or name.startswith("random"):
            continue
        random_agent = agents.get("random_episodic" if agent.episodic else "random_continuous")
        for family in families:
            mdps = bench_mdps(family, agent.episodic, args.mdps)
            m = measure_ratio(agent, random_agent, mdps, seeds, args.steps, max(args.repeats, 1))
            rows.append(dict(agent=name, mdp=family, S=mdps[0].n_states, mdps=len(mdps), seeds=seeds, **m))
            print(f"{name:24s} {family:14s} seeds={seeds}: random {fmt_rate(m['random_steps_per_s'])}, agent "
                  f"{fmt_rate(m['agent_steps_per_s'])} agent-steps/s, cost ratio {m['ratio']:.2f}x; ns env "
                  f"{m['env_ns']:.0f}, agent {m['agent_ns']:.0f}, indicators {m['indicators_ns']:.0f} (random's "
                  f"{m['random_indicators_ns']:.0f})", flush=True)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "bench_agents_ratio.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["agent"])
        w.writeheader()
        w.writerows(rows)
    lines = [
        f"{args.steps} steps per seed, {seeds} members on {args.mdps} MDP(s), {jax.local_device_count()} host devices; "
        "the random agent and "
        f"the agent, each with indicators every 100 steps and without, interleaved {max(args.repeats, 1)} times, "
        f"best of each. Load average before/after: {load0[0]:.1f} / {os.getloadavg()[0]:.1f}.",
        "",
        "| agent | MDP | random | agent | cost ratio | ns env / agent / indicators (random's indicators) |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['agent']} | {r['mdp']} | {fmt_rate(r['random_steps_per_s'])} | "
                     f"{fmt_rate(r['agent_steps_per_s'])} | {r['ratio']:.2f}x | {r['env_ns']:.0f} / "
                     f"{r['agent_ns']:.0f} / {r['indicators_ns']:.0f} ({r['random_indicators_ns']:.0f}) |")
    args.update_docs = False  # docs/performance.md has the throughput table; this one stays in results/benchmarks
    _common.publish("bench_agents_ratio", "Cost per step against the random agent (same process)", lines, args,
                    sys.argv[1:] if argv is None else argv)
    main_deep_ratio(args, names, argv)


def main_deep_ratio(args, names: list[str], argv: Sequence[str] | None = None) -> None:
    """``--ratio``, deep agents: each against DQN of its setting on :func:`deep_mdp`, at the largest deep seed count."""
    seeds = [int(s) for s in args.deep_seeds.split(",")][-1]
    load0 = os.getloadavg()
    rows = []
    for name in names:
        agent = agents.get(name)
        if agent.observation != "emission" or name.startswith("dqn"):
            continue
        dqn = agents.get("dqn_episodic" if agent.episodic else "dqn_continuous")
        ns = interleaved_ns({"dqn": (dqn, 100), "agent": (agent, 100)}, [deep_mdp(agent.episodic)], seeds, args.steps,
                            max(args.repeats, 1))
        ratio = ns["agent"] / ns["dqn"]
        rows.append(dict(agent=name, seeds=seeds, dqn_ns=ns["dqn"], agent_ns=ns["agent"], ratio=ratio))
        print(f"{name:28s} seeds={seeds}: DQN {ns['dqn']:.0f} ns, agent {ns['agent']:.0f} ns per agent-step, cost "
              f"ratio {rows[-1]['ratio']:.2f}x", flush=True)
    if not rows:
        return
    lines = [
        f"{args.steps} steps per seed, {seeds} seeds on RiverSwim through `state_info`, indicators every 100 steps, "
        f"{jax.local_device_count()} host devices; DQN and the agent interleaved {max(args.repeats, 1)} times, best of "
        f"each. Load average before/after: {load0[0]:.1f} / {os.getloadavg()[0]:.1f}.",
        "",
        "| agent | seeds | DQN ns per agent-step | agent ns per agent-step | cost ratio |",
        "|---|---|---|---|---|",
        *(f"| {r['agent']} | {r['seeds']} | {r['dqn_ns']:.0f} | {r['agent_ns']:.0f} | {r['ratio']:.2f}x |"
          for r in rows),
    ]
    args.update_docs = False
    _common.publish("bench_agents_deep_ratio", "Deep agents' cost per step against DQN's (same process)", lines, args,
                    sys.argv[1:] if argv is None else argv)


def fmt_rate(x: float) -> str:
    return f"{x / 1e6:.2f} M" if x >= 1e6 else f"{x / 1e3:.1f} k"


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=None,
                    help="steps per seed (default 20 000, as the reference timed; --quick: 4 000)")
    ap.add_argument("--seeds", default="1,64,1024")
    ap.add_argument("--deep-seeds", default="1,16,64", help="seed counts of the deep agents")
    ap.add_argument("--bsuite-steps", type=int, default=3_000, help="timed steps of bsuite's DQN loop")
    ap.add_argument("--agents", default=",".join(agents.AGENTS))
    ap.add_argument("--mdps", type=int, default=1,
                    help="tabular agents: spread each seed count's members over this many MDPs of the benchmark MDP's "
                         "family and parameters (seeds 0 .. N-1), a stack of MDPs as in every batch of the benchmark; "
                         "each seed count must be a multiple of it (default 1: one MDP)")
    ap.add_argument("--repeats", type=int, default=None, help="timed runs per measurement (default 2; --quick: 1)")
    ap.add_argument("--quick", action="store_true",
                    help="4 000 steps and 1 repeat, unless --steps or --repeats say otherwise")
    ap.add_argument("--max-seconds", type=float, default=120.0,
                    help="skip a seed count whose predicted run time exceeds this")
    ap.add_argument("--ratio", action="store_true",
                    help="each tabular agent's cost per step against the random agent's, same process, at the largest "
                         "seed count (module docstring)")
    _common.add_common_args(ap)
    args = ap.parse_args(argv)
    if args.smoke:  # the random agent alone on RiverSwim, one seed, few steps, no profile
        args.agents, args.seeds, args.deep_seeds, args.steps, args.repeats = "random_continuous", "1", "1", 100, 0
    cache_folder, compile_stats = compilation.setup_compilation(args.no_compile_cache)
    t_script = time.perf_counter()
    if args.steps is None:  # an explicit --steps stands, with --quick too
        args.steps = 4_000 if args.quick else 20_000
    if args.repeats is None:  # an explicit --repeats stands, with --quick too
        args.repeats = 1 if args.quick else 2
    seed_counts = [int(s) for s in args.seeds.split(",")]
    if args.mdps < 1 or any(n % args.mdps for n in seed_counts):
        ap.error(f"--mdps must be a positive divisor of every seed count (--seeds {args.seeds}); got {args.mdps}")
    deep_seed_counts = [int(s) for s in args.deep_seeds.split(",")]
    names = [n for n in args.agents.split(",") if n]
    families = [f for f in ("RiverSwim", "Taxi", "MiniGridEmpty") if f in jaxmdp.families()]
    if args.smoke:
        families = ["RiverSwim"]
    if args.ratio:
        main_ratio(args, names, families, argv)
        print(compilation.time_report(time.perf_counter() - t_script, compile_stats.snapshot(), cache_folder),
              file=sys.stderr)
        return 0

    rows, profile = [], []
    for name in names:
        agent = agents.get(name)
        deep = agent.observation == "emission"
        for family in ("RiverSwim",) if deep else families:
            mdps = bench_mdps(family, agent.episodic, 1 if deep else args.mdps)
            mdp = mdps[0]
            if deep:
                mdp = deep_mdp(agent.episodic)
                mdps = [mdp]
                if name.startswith("dqn"):
                    base = bsuite_dqn_steps_per_s(mdp.mdp, mdp.emissions, agent.default_hparams, args.bsuite_steps)
                    print(f"bsuite JAX DQN {family}: " + ("not installed" if base is None else
                                                          f"{fmt_rate(base['steps_per_s'])} steps/s"), flush=True)
                    if base is not None:
                        rows.append(dict(agent=f"bsuite_jax_dqn ({'episodic' if agent.episodic else 'continuous'})",
                                         mdp=family, S=mdp.n_states, seeds=1, skipped=False, compile_s=float("nan"),
                                         cpu_ns_per_step=float("nan"), regret=float("nan"), **base))
            predicted = None
            for seeds in deep_seed_counts if deep else seed_counts:
                if predicted is not None and predicted * seeds > args.max_seconds:
                    print(f"{name} {family} {seeds} seeds: skipped (predicted {predicted * seeds:.0f} s)",
                          flush=True)
                    rows.append(dict(agent=name, mdp=family, S=mdp.n_states, seeds=seeds, skipped=True))
                    continue
                m = measure(agent, mdps, seeds, args.steps, args.repeats)
                predicted = args.steps / m["steps_per_s"]  # seconds per seed at this rate (optimistic)
                rows.append(dict(agent=name, mdp=family, S=mdp.n_states, seeds=seeds, skipped=False, **m))
                print(f"{name:24s} {family:14s} seeds={seeds:5d} {fmt_rate(m['steps_per_s'])} agent-steps/s "
                      f"(compile {m['compile_s']:.1f} s, {m['cpu_ns_per_step']:.0f} CPU-ns/step)", flush=True)
        # Profile at the largest seed count on RiverSwim: environment, agent, indicators (tabular agents).
        seeds = seed_counts[-1]
        if args.smoke or deep or not any(r["agent"] == name and r["seeds"] == seeds and not r["skipped"] for r in rows):
            continue
        mdps = bench_mdps("RiverSwim", agent.episodic, args.mdps)
        random_agent = agents.get("random_episodic" if agent.episodic else "random_continuous")
        env = measure(random_agent, mdps, seeds, args.steps, args.repeats, log_period=NO_INDICATORS)
        bare = measure(agent, mdps, seeds, args.steps, args.repeats, log_period=NO_INDICATORS)
        full = measure(agent, mdps, seeds, args.steps, args.repeats)
        one_core = measure(agent, mdps, seeds, args.steps, args.repeats, shards=1)
        ns = lambda m: 1e9 / m["steps_per_s"]  # noqa: E731
        profile.append(dict(
            agent=name, seeds=seeds, env_ns=ns(env), agent_ns=ns(bare) - ns(env), indicators_ns=ns(full) - ns(bare),
            total_ns=ns(full), env_cpu_ns=env["cpu_ns_per_step"],
            agent_cpu_ns=bare["cpu_ns_per_step"] - env["cpu_ns_per_step"],
            indicators_cpu_ns=full["cpu_ns_per_step"] - bare["cpu_ns_per_step"], total_cpu_ns=full["cpu_ns_per_step"],
            one_core_steps_per_s=one_core["steps_per_s"], all_cores_steps_per_s=full["steps_per_s"],
        ))
        p = profile[-1]
        print(f"  profile {name}: env {p['env_ns']:.0f} ns, agent {p['agent_ns']:.0f} ns, indicators "
              f"{p['indicators_ns']:.0f} ns per agent-step; 1 core {fmt_rate(p['one_core_steps_per_s'])}/s",
              flush=True)

    write_csv(args.out, rows)
    _common.publish(NAME, "Agents", body(rows, profile, args), args, argv)
    print(compilation.time_report(time.perf_counter() - t_script, compile_stats.snapshot(), cache_folder),
          file=sys.stderr)
    return 0


def write_csv(out, rows: list[dict]) -> None:
    """``bench_agents.csv``: one row per measurement (a skipped one has only its keys and ``skipped``)."""
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "bench_agents.csv", "w", newline="") as f:
        fields = ["agent", "mdp", "S", "seeds", "skipped", "steps_per_s", "compile_s", "cpu_ns_per_step", "regret"]
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def cell(r: dict | None) -> str:
    """A table cell: the rate with its compile time, ``skipped`` or ``-`` (not measured)."""
    if r is None:
        return "-"
    if r["skipped"]:  # a skipped configuration has no measurements
        return "skipped"
    compile_s = r.get("compile_s", float("nan"))
    return fmt_rate(r["steps_per_s"]) + ("" if math.isnan(compile_s) else f" ({compile_s:.1f} s)")  # bsuite: none


def body(rows: list[dict], profile: list[dict], args) -> list[str]:
    """The tables' lines: throughput per agent, MDP and seed count; bsuite's DQN beside ours; the profile."""
    seed_counts = sorted({r["seeds"] for r in rows})
    lines = [
        f"{args.steps} steps per seed, exact indicators every 100 steps, {jax.local_device_count()} host devices "
        f"(one per core). Best of {args.repeats + 1} runs."
        + (f" Tabular agents: each seed count's members spread over {args.mdps} MDPs of the family (--mdps)."
           if args.mdps > 1 else ""),
        "",
        "Agent-steps per second summed over seeds (compile time in brackets); the reference runs one seed per "
        "process (docs/benchmark.md §10).",
        "",
        "| agent | MDP | S | " + " | ".join(f"{s} seeds" for s in seed_counts) + " | reference (1 seed) |",
        "|---|---|---|" + "---|" * len(seed_counts) + "---|",
    ]
    keys = sorted({(r["agent"], r["mdp"], r["S"]) for r in rows}, key=lambda k: (list(agents.AGENTS).index(k[0])
                                                                                 if k[0] in agents.AGENTS else 99, k[1]))
    for agent, mdp, S in keys:
        cells = [cell(next((r for r in rows if (r["agent"], r["mdp"], r["seeds"]) == (agent, mdp, s)), None))
                 for s in seed_counts]
        lines.append(f"| {agent} | {mdp} | {S} | " + " | ".join(cells) + f" | {REFERENCE.get((agent, mdp), '-')} |")
    baselines = [r for r in rows if r["agent"].startswith("bsuite_jax_dqn")]
    if not baselines and any(r["agent"].startswith("dqn_") for r in rows):
        lines += ["", "bsuite is not installed (`pip install -e .[bench]`): no comparison with its JAX DQN."]
    if baselines:
        lines += ["", "Deep agents against bsuite's own JAX DQN (one seed, per-step Python loop, same MDP, observations, "
                  "network, batch and replay): our agent-steps/s summed over seeds divided by bsuite's steps/s.", "",
                  "| agent | seeds | ours | bsuite JAX DQN | ratio |", "|---|---|---|---|---|"]
        for base in baselines:
            setting = "episodic" if "episodic" in base["agent"] else "continuous"
            for r in rows:
                if r["agent"] == f"dqn_{setting}" and not r.get("skipped"):
                    lines.append(f"| {r['agent']} | {r['seeds']} | {fmt_rate(r['steps_per_s'])} | "
                                 f"{fmt_rate(base['steps_per_s'])} | {r['steps_per_s'] / base['steps_per_s']:.1f}x |")
    if profile:
        lines += [
            "",
            f"Where the time goes on RiverSwim at {profile[0]['seeds']} seeds, per agent-step (wall ns, then CPU ns "
            "over all threads): environment = random agent without indicators; agent = the agent without indicators "
            "minus the environment; indicators = the rest. 1 core: the same run on one host device.",
            "",
            "| agent | env | agent | indicators | total | CPU env / agent / indicators | 1 core | all cores |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for p in profile:
            lines.append(
                f"| {p['agent']} | {p['env_ns']:.0f} | {p['agent_ns']:.0f} | {p['indicators_ns']:.0f} | "
                f"{p['total_ns']:.0f} | {p['env_cpu_ns']:.0f} / {p['agent_cpu_ns']:.0f} / "
                f"{p['indicators_cpu_ns']:.0f} | {fmt_rate(p['one_core_steps_per_s'])} | "
                f"{fmt_rate(p['all_cores_steps_per_s'])} |"
            )
    return lines


if __name__ == "__main__":
    sys.exit(main())
