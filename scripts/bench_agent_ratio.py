"""An agent's cost per step against the random agent's, measured back to back in one process (a shared machine's
load then weighs on both): for each benchmark MDP of ``bench_agents.py``, the random agent and the agent, each with
indicators every 100 steps and without, best of 2 runs after a compiling one.

Usage: ``python scripts/bench_agent_ratio.py [families] [seeds] [agents] [steps]``, e.g.
``python scripts/bench_agent_ratio.py RiverSwim,Taxi,MiniGridEmpty 1024 q_learning_episodic 4000``.
"""

from jaxmdp.experiment.devices import use_every_core

use_every_core()  # before any JAX computation

import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import agents  # noqa: E402
import jaxmdp  # noqa: E402
from jaxmdp.experiment import runner  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from bench_agents import BENCH_MDPS, NO_INDICATORS  # noqa: E402


def rate(agent, mdp, seeds: int, steps: int, log_period: int = 100, repeats: int = 2) -> float:
    """Agent-steps per second, best of ``repeats`` after a first (compiling) run."""
    g = runner.product([mdp], [agent.default_hparams], seeds=range(seeds))
    runner.run(agent, g, steps, log_period=log_period, n_records=10)
    best = min(runner.run(agent, g, steps, log_period=log_period, n_records=10).run_s for _ in range(repeats))
    return steps * seeds / best


def main() -> None:
    fams = sys.argv[1].split(",") if len(sys.argv) > 1 else ["RiverSwim", "Taxi", "MiniGridEmpty"]
    seeds = int(sys.argv[2]) if len(sys.argv) > 2 else 1024
    names = sys.argv[3].split(",") if len(sys.argv) > 3 else ["q_learning_episodic"]
    steps = int(sys.argv[4]) if len(sys.argv) > 4 else 4000
    for fam in fams:
        for name in names:
            ag = agents.get(name)
            mdp = jaxmdp.make(fam, episodic=ag.episodic, seed=0, **BENCH_MDPS[(fam, ag.episodic)])
            rnd = agents.get("random_episodic" if ag.episodic else "random_continuous")
            r_env, r_rnd = rate(rnd, mdp, seeds, steps, NO_INDICATORS), rate(rnd, mdp, seeds, steps)
            r_bare, r_full = rate(ag, mdp, seeds, steps, NO_INDICATORS), rate(ag, mdp, seeds, steps)
            ns = lambda r: 1e9 / r  # noqa: E731
            print(f"{fam} S={mdp.n_states} A={mdp.n_actions} H={mdp.H} {name} seeds={seeds}: random "
                  f"{r_rnd / 1e6:.2f} M, agent {r_full / 1e6:.2f} M (cost ratio {r_rnd / r_full:.2f}x); ns env "
                  f"{ns(r_env):.0f} agent {ns(r_bare) - ns(r_env):.0f} indicators {ns(r_full) - ns(r_bare):.0f} "
                  f"(random's indicators {ns(r_rnd) - ns(r_env):.0f})", flush=True)


if __name__ == "__main__":
    main()
