"""Benchmark: what a planning round of the runner costs the agents that plan, beyond the plan itself.

The runner plans the members that asked in rounds (:func:`jaxmdp.experiment.planning.plan_due`): it gathers their
agent states into the round's slots, plans them and scatters the states back. Late in a continuous run most rounds
hold one member; a shard of at most 16 members plans with one slot (episodic PSRL too, e.g. ``--agents
psrl_episodic --set "episodic communicating" --label MiniGridEmpty/prms_3 --members 16``). For each agent,
``--members`` members of one benchmark MDP (default: the communicating set's MiniGrid-Rooms ``prms_0``, 948 states,
a shard of its size bucket) after ``--play`` uniformly random steps (``update`` only) and a plan, one member due;
timed in turn, best of ``--repeats``: a round whose plan returns the state unchanged (the data movement alone), a
round with the agent's plan, and the agent's plan of that member alone (a ``vmap`` of one, no round), with the agent
state's bytes per member.

Run it in two checkouts to compare them (docs/benchmarks/bench_plan_rounds.md):

    PYTHONPATH=$PWD python scripts/bench_plan_rounds.py --agents psrl_continuous ucrl2
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp

import agents
from agents import psrl_continuous
from hardness.benchmark import sets
from jaxmdp.agent_interface import Transition
from jaxmdp.experiment.agent_interface import spec_of
from jaxmdp.experiment.planning import plan_due

from bench_doc import append_section, interleaved_best  # scripts/ is on the path of a script run as python scripts/NAME.py


def played_states(agent, mdp, members: int, play: int, seed: int = 0):
    """``members`` fresh agent states after ``play`` uniformly random transitions of ``mdp`` each, then one plan."""
    spec = spec_of(mdp, 500_000)
    hp = agent.default_hparams
    if agent.name == "psrl_continuous":  # the plan's buffer at the MDP's own psi, as the benchmark sizes it
        hp = hp.replace(max_psi=psrl_continuous.psi(hp, mdp.n_states, mdp.n_actions))
    keys = jax.random.split(jax.random.key(seed), members)
    states = jax.vmap(lambda k: agent.init(k, spec, hp))(keys)
    n_real = int(mdp.state_mask.sum())
    n_actions = int(mdp.action_mask.sum())

    def fold(st, key):
        ks, ka, kn = jax.random.split(key, 3)
        s = jax.random.randint(ks, (members,), 0, n_real)
        a = jax.random.randint(ka, (members,), 0, n_actions)
        nxt = jax.vmap(lambda s, a, k: jax.random.choice(k, mdp.n_states, p=mdp.T[s, a]))(
            s, a, jax.random.split(kn, members))
        tr = Transition(obs=s, action=a, reward=mdp.R[s, a], next_obs=nxt, h=jnp.zeros(members, jnp.int32),
                        terminated=jnp.zeros(members, bool))
        return jax.vmap(agent.update)(st, tr), None

    states = jax.jit(lambda st: jax.lax.scan(fold, st, jax.random.split(jax.random.key(seed + 1), play))[0])(states)
    return jax.jit(jax.vmap(agent.plan))(keys, states.replace(plan_due=jnp.ones(members, bool)))


def measure(agent_name: str, set_name: str, label: str, members: int, play: int, repeats: int) -> dict:
    agent = agents.get(agent_name)
    mdp = sets.instance(set_name, label).build(0)
    states = played_states(agent, mdp, members, play)
    due = jnp.zeros(members, bool).at[min(1, members - 1)].set(True)
    states = states.replace(plan_due=due)
    keys = jax.random.split(jax.random.key(7), members)
    i = int(jnp.argmax(due))
    one = jax.tree.map(lambda x: x[i:i + 1], states)

    def unchanged(key, state):
        return state.replace(plan_due=jnp.zeros((), bool))

    fns = {
        "identity round": jax.jit(lambda k, s, d, o: plan_due(unchanged, 1, d, k, s, whole_batch=False)),
        "plan round": jax.jit(lambda k, s, d, o: plan_due(agent.plan, 1, d, k, s, whole_batch=False)),
        "plan alone": jax.jit(lambda k, s, d, o: jax.vmap(agent.plan)(k[i:i + 1], o)),
    }
    best = interleaved_best(fns, (keys, states, due, one), repeats)
    return dict(agent=agent_name, mdp=label, S=mdp.n_states, members=members, play=play,
                state_bytes=sum(x.nbytes for x in jax.tree.leaves(one)), **{k: 1e3 * v for k, v in best.items()})


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--agents", nargs="+", default=["psrl_continuous", "ucrl2"])
    ap.add_argument("--set", default="continuous communicating")
    ap.add_argument("--label", default="MiniGridRooms/prms_0")
    ap.add_argument("--members", type=int, default=4)
    ap.add_argument("--play", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--doc", default=None, help="append the table to this Markdown file")
    args = ap.parse_args(argv)
    rows = [measure(a, args.set, args.label, args.members, args.play, args.repeats) for a in args.agents]
    lines = ["| agent | MDP (S) | members | state MB / member | identity round ms | plan round ms | plan alone ms |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['agent']} | {r['mdp']} ({r['S']}) | {r['members']} | {r['state_bytes'] / 1e6:.2f} | "
                     f"{r['identity round']:.2f} | {r['plan round']:.2f} | {r['plan alone']:.2f} |")
    print("\n".join(lines))
    if args.doc:
        append_section(args.doc, "Planning rounds: the data movement around a plan", argv, lines)
    return rows


if __name__ == "__main__":
    main()
