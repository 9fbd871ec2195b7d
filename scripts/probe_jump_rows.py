"""How many of a PSRL continuous plan's chosen rows are jumps (docs/benchmarks/continuous_planning.md, "PSRL
continuous: evaluations that skip the jumping states").

For each ``--labels`` MDP of ``--set`` (seed 0; tuned hyperparameters with ``max_psi = psi``) and each ``--steps``
count: the agent's state after that many uniformly random steps, a cold plan and 200 further steps; then, for
``--keys`` plan keys, policy iteration on the extended MDP and, for its final policy, the number of evaluations, of
chosen posterior rows, of chosen rows that jump (``p^- = 0``: all mass on the candidate's state ``z``) and of distinct
states jumped to: the size of the system that ``dp.discounted_jump_chain_values`` solves.

    python scripts/probe_jump_rows.py --labels MiniGridRooms/prms_1 --steps 2000 20000
"""

from __future__ import annotations

import argparse
import json

import jax
import jax.numpy as jnp
import numpy as np

import agents
import agents.psrl_continuous as pc
from hardness.benchmark import sets

from profile_continuous_plans import warm_state  # scripts/ is on the path of a script run as python scripts/NAME.py


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--set", default="continuous ergodic")
    p.add_argument("--labels", nargs="+", default=["MiniGridRooms/prms_1"])
    p.add_argument("--steps", type=int, nargs="+", default=[2000, 20000])
    p.add_argument("--keys", type=int, default=3)
    return p


@jax.jit
def _final_choice(state, key):
    """Policy iteration of :func:`pc.plan` with ``key``: its evaluations, and its final policy's chosen rows."""
    R, d = pc.extended_draws(key, state)
    gamma = jnp.asarray(state.hparams.discount, R.dtype)
    res = pc.extended_policy_iteration(d, R, gamma, state.u, state.action_mask)
    _, choice = pc._greedy(d, R, res.V, gamma, state.action_mask)
    return res.iterations, d.posterior[jnp.arange(choice.action.shape[0]), choice.action], choice.jump


def probe(state, key) -> dict:
    """Counts of the final policy of one plan from ``state`` with ``key`` (module docstring)."""
    evaluations, posterior, jump = (np.asarray(x) for x in _final_choice(state, key))
    real = np.asarray(state.state_mask)
    jump = jump[real]
    return dict(evaluations=int(evaluations), posterior_rows=int(posterior[real].sum()),
                jumping_rows=int((jump >= 0).sum()), real_states=int(real.sum()),
                distinct_targets=len(np.unique(jump[jump >= 0])))


def main(argv: list[str] | None = None) -> list[dict]:
    args = build_parser().parse_args(argv)
    agent = agents.get("psrl_continuous")
    rows = []
    for label in args.labels:
        mdp = sets.instance(args.set, label).build(0)
        S, A = int(np.sum(np.asarray(mdp.state_mask))), int(np.sum(np.asarray(mdp.action_mask)))
        hp = agent.default_hparams.replace(max_psi=pc.psi(agent.default_hparams, S, A))
        for steps in args.steps:
            state = warm_state(agent, mdp, hp, steps, 200)
            for i in range(args.keys):
                row = dict(mdp=label, steps=steps, key=i, **probe(state, jax.random.key(10 + i)))
                print(json.dumps(row), flush=True)
                rows.append(row)
    return rows


if __name__ == "__main__":
    main()
