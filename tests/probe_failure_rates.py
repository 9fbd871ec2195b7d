"""Measure the per-seed failure rate of the learning tests' criteria on many seeds (not part of the default run:
pytest collects ``test_*.py`` only). The learning tests allow ``stat_checks.allowed_failures(n, q_u)`` failures of
their ``n`` seeds, where ``q_u`` is the Clopper-Pearson bound (miss probability 1e-3) of the rate measured here.

    PYTHONPATH=$PWD nice -n 19 python tests/probe_failure_rates.py GROUP [--seeds N] [--chunk C] [--first F]

Seeds ``F, F + 1, ...`` (default ``F = 10**6``, away from the tests' defaults), run ``C`` at a time in lockstep
(agent-loop probes: each chunk's ``4 C`` member keys split from the key of its first seed, a quarter per probe;
deep agents: the chunk's grid of ``C`` seeds by 2 epsilons or learning rates, every member its own key; the counts are
then of members). Prints one row per criterion: label, seeds, failures, q_u, and the first failing seeds (deep agents:
also the quantiles of the members' margins, their error in units of the tolerance).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
from stat_checks import failure_rate_bound  # noqa: E402


def q_learning():
    import test_agents as t

    return {label: (lambda seeds, label=label: t.q_learning_passes(label, seeds)[0]) for label in t.Q_AGENTS}


def agent_loop_probes(module: str):
    """The agent-loop probes of ``module`` (4 probes, a quarter of the members each): seeds -> member keys."""

    def group():
        import jax

        t = __import__(module)
        return {module: lambda seeds: t.probe_passes(jax.random.split(jax.random.key(seeds[0]), 4 * len(seeds)))}

    return group


def q_deep(module: str, names: tuple[str, ...]):
    """DQN / BootDQN on the q_probes: each chunk is the [epsilons x C] grid from the key of its first seed."""

    def group():
        import q_probes

        t = __import__(module)
        return {f"{name}-{probe}": (lambda seeds, name=name, probe=probe: t.probe_margins(
            name, probe, t.run_probe(name, probe, base=seeds[0], n_seeds=len(seeds))))
            for name in names for probe in q_probes.PROBES}

    return group


def actor_critic():
    """The actor-critic probes: each chunk is the [learning rates x C] grid from the key of its first seed."""
    import actor_critic_probes as probes
    import test_actor_critic
    import test_actor_critic_rnn

    import agents

    out = {}
    for module in (test_actor_critic, test_actor_critic_rnn):
        tests = module.TestProbeLearning()
        for name in sorted({n for n, _ in tests.q_learn}):
            agent = agents.get(name)
            runner = probes.grid_runner(agent, probes.N_STEPS[agent.episodic])
            for kind in ("bandit", "constant", "chain"):
                out[f"{name}-{kind}"] = (lambda seeds, tests=tests, agent=agent, runner=runner, kind=kind: tests.margins(
                    agent, probes.run_probe(runner, agent, kind, base=seeds[0], n_seeds=len(seeds)), kind))
    return out


GROUPS = {"dqn": q_deep("test_dqn", ("dqn_episodic", "dqn_continuous")),
          "boot_dqn": q_deep("test_boot_dqn", ("boot_dqn_episodic", "boot_dqn_continuous")),
          "actor_critic": actor_critic, "q_learning": q_learning, "ucrl2": agent_loop_probes("test_ucrl2"),
          "psrl_episodic": agent_loop_probes("test_psrl_episodic"),
          "psrl_continuous": agent_loop_probes("test_psrl_continuous")}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("group", choices=sorted(GROUPS))
    parser.add_argument("--seeds", type=int, default=1024)
    parser.add_argument("--chunk", type=int, default=256)
    parser.add_argument("--first", type=int, default=10**6)
    parser.add_argument("--only", help="run only the criteria whose label contains this")
    args = parser.parse_args(argv)
    for label, passes in GROUPS[args.group]().items():
        if args.only and args.only not in label:
            continue
        start, rows = time.perf_counter(), {}  # sub-label -> (failed, members, margins)
        for lo in range(args.first, args.first + args.seeds, args.chunk):
            seeds = range(lo, min(lo + args.chunk, args.first + args.seeds))
            outs = passes(seeds)  # passed, margins (pass: <= 1), or a dict of either by criterion
            for sub, out in (outs.items() if isinstance(outs, dict) else [("", outs)]):
                failed, n, margins = rows.setdefault(f"{label} {sub}".strip(), ([], [0], []))
                out = np.asarray(out).ravel()
                if out.dtype != bool:
                    margins.append(out)
                    out = out <= 1.0
                n[0] += out.size
                failed += [seeds[i] if out.size == len(seeds) else (seeds[0], int(i)) for i in np.flatnonzero(~out)]
        for row, (failed, n, margins) in rows.items():
            q_u = failure_rate_bound(len(failed), n[0])
            print(f"| {args.group} | {row} | {n[0]} | {len(failed)} | {q_u:.2e} | {time.perf_counter() - start:.0f} s"
                  f" | {failed[:10]} |", flush=True)
            if margins:
                quantiles = np.quantile(np.concatenate(margins), [0.5, 0.9, 0.99, 1.0])
                print(f"    margins (error / tolerance) at quantiles 0.5, 0.9, 0.99, 1: {np.round(quantiles, 3).tolist()}",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
