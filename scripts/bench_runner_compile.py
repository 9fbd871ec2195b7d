"""Benchmark: how long the runner takes to compile each tabular agent's programs, and a digest of what they compute.

For every agent (both variants for the planning agents), one ``runner.run`` on a small grid of RiverSwim MDPs
(episodic: sizes 3-6, continuous: 4 and 6 with lazy steps and Beta rewards; three seeds each), 300 steps; with
``--banded`` the continuous agents run on two MiniGridEmpty MDPs of 100 and 144 states instead, whose exact gains the
runner takes on each member's band order (``runner._band``, on a CPU). Reported:
``RunResult.compile_s`` (the indicator constants, the initialisation and the chunk program, compiled together), best
of ``--repeats`` with JAX's in-memory caches cleared between repeats, and a SHA-256 prefix of the records and the
final agent states, so that two commits can be compared for speed and for identical results.

    python scripts/bench_runner_compile.py
    python scripts/bench_runner_compile.py --agents psrl_continuous --repeats 3
    python scripts/bench_runner_compile.py --agents q_learning_continuous,ucrl2,psrl_continuous --banded

Appends a section to ``docs/benchmarks/bench_runner_compile.md`` (with the command and the commit) unless ``--doc ''``.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

DEFAULT_AGENTS = ("q_learning_episodic", "psrl_episodic", "q_learning_continuous", "ucrl2", "psrl_continuous")


def _grid(agent, banded: bool = False):
    import jaxmdp
    from jaxmdp.experiment import runner

    if banded and not agent.episodic:
        mdps = [jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=n, p_lazy=0.3, n_starting_states=2,
                            make_reward_stochastic=True) for n in (5, 6)]
    elif agent.episodic:
        mdps = [jaxmdp.make("RiverSwim", episodic=True, seed=0, size=n, randomize_actions=False) for n in (3, 4, 5, 6)]
    else:
        mdps = [jaxmdp.make("RiverSwim", episodic=False, seed=0, size=n, randomize_actions=False, p_lazy=0.1,
                            make_reward_stochastic=True) for n in (4, 6)]
    return runner.product(mdps, [agent.default_hparams], seeds=[0, 1, 2])


def measure(name: str, variant: str, repeats: int, banded: bool = False) -> dict:
    """Best compile seconds of ``repeats`` cold compilations and the digest of the run's results."""
    import jax
    import numpy as np

    import agents
    from jaxmdp.experiment import runner

    agent = agents.get(name, variant)
    grid = _grid(agent, banded)
    best, digest = float("inf"), None
    for _ in range(repeats):
        jax.clear_caches()
        for cache in (runner._init_program, runner._chunk_program, runner._constants_program):
            cache.cache_clear()
        res = runner.run(agent, grid, 300, log_period=10, n_records=5)
        h = hashlib.sha256(np.asarray(res.values).tobytes())
        for leaf in jax.tree.leaves(res.agent_state):
            h.update(np.asarray(leaf).tobytes())
        assert digest in (None, h.hexdigest()), "the same run gave different results"
        digest, best = h.hexdigest(), min(best, res.compile_s)
    return {"agent": f"{name}@{variant}", "compile_s": best, "digest": digest[:16]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--agents", default=",".join(DEFAULT_AGENTS), help="comma-separated agent names")
    p.add_argument("--repeats", type=int, default=2, help="cold compilations per agent (best kept)")
    p.add_argument("--banded", action="store_true",
                   help="continuous agents on MDPs of 100 and 144 states, whose exact gains are banded")
    p.add_argument("--doc", default=str(ROOT / "docs" / "benchmarks" / "bench_runner_compile.md"),
                   help="Markdown report to append to ('' for none)")
    args = p.parse_args()
    if args.repeats < 1:
        p.error("--repeats must be at least 1")
    import agents

    rows = []
    for name in args.agents.split(","):
        for variant in ("paper", "colosseum") if agents.get(name).plans else ("paper",):
            rows.append(measure(name, variant, args.repeats, args.banded))
            r = rows[-1]
            print(f"{r['agent']:28s} compile {r['compile_s']:6.1f} s  digest {r['digest']}", flush=True)
    if args.doc:
        import jax

        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                                text=True).stdout.strip() or "unknown"
        cmd = "python scripts/bench_runner_compile.py" + "".join(
            f" --{k} {v}" for k, v in (("agents", args.agents), ("repeats", args.repeats))
            if str(v) != str(p.get_default(k))) + (" --banded" if args.banded else "")
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        lines = [
            f"## {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, commit {commit}",
            "",
            f"    {cmd}",
            "",
            f"jax {jax.__version__}, backend {jax.default_backend()}, {platform.machine()}, {os.cpu_count()} cores; "
            f"load average at the end {load:.1f}.",
            "",
            "| agent | compile s (best of {}) | results digest |".format(args.repeats),
            "|---|---|---|",
        ]
        lines += [f"| {r['agent']} | {r['compile_s']:.1f} | `{r['digest']}` |" for r in rows]
        doc = Path(args.doc)
        head = "" if doc.exists() else (
            "# The runner's compile time per agent\n\n"
            "`scripts/bench_runner_compile.py`: each agent's runner programs compiled cold on a small grid (its "
            "docstring); the digest identifies the results, so equal digests across commits mean bit-identical "
            "records and final agent states.\n\n")
        with doc.open("a") as f:
            f.write(head + "\n".join(lines) + "\n\n")
        print(f"appended to {doc}")


if __name__ == "__main__":
    main()
