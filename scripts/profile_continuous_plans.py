"""Profile one epoch plan of the continuous model-based agents (PSRL continuous, UCRL2) at the benchmark's sizes.

For each chosen MDP of a continuous benchmark set (default: the largest MDP of every size bucket of "continuous
ergodic"), the agent first takes ``--steps`` uniformly random actions (its ``update`` only, no planning: counts and
reward statistics as after that many steps of play), then plans twice: a cold plan (bias ``u = 0``) and, after
``--more`` further random steps, a warm one (from the first plan's ``u``, as the agent's next epoch does). Each is
timed (best of ``--repeats`` compiled calls, one member) with its planner's iteration count; PSRL's plan is split
into its reward draw, its candidate draws (``agents.psrl_continuous.draws``: the simple optimistic sampling's states
and, when kept, the posterior Dirichlet draws; the dense candidate kernels before the structured plan) and the rest
(policy iteration on the extended MDP).

    python scripts/profile_continuous_plans.py --agents psrl_continuous ucrl2 --steps 5000
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxmdp
from agents import AGENTS
from agents import psrl_continuous as pc
from agents.posteriors import normal_gamma_sample
from hardness.benchmark import run, sets
from jaxmdp.experiment.agent_interface import Transition, spec_of


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--set", default="continuous ergodic", help="benchmark set (%(default)s)")
    p.add_argument("--agents", nargs="+", default=["psrl_continuous", "ucrl2"])
    p.add_argument("--labels", nargs="+", default=None, help="MDP labels (default: each bucket's largest)")
    p.add_argument("--steps", type=int, default=5000, help="random steps folded in before the first plan")
    p.add_argument("--more", type=int, default=200, help="random steps between the cold and the warm plan")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", default=None, help="write the rows as JSON here")
    return p


def bucket_labels(set_name: str) -> list[str]:
    """The largest MDP (seed 0) of each size bucket of the full benchmark's plan for ``set_name``."""
    cfg = run.RunConfig(sets=(set_name,), hparams="reference", seeds=(0,), n_steps=500_000, n_buckets=4)
    _, batches = run.plan(cfg)
    sizes = {inst.label: inst.build(0).n_states for inst in sets.instances(set_name)}
    out = []
    for b in batches:
        if b.agent == run.default_agents(set_name)[0]:
            out.append(max(sorted({m for m, _ in b.members}), key=lambda m: sizes[m]))
    return out


def played(agent, mdp, hp, n_steps: int, key, state=None):
    """The agent's state after ``n_steps`` uniformly random actions on ``mdp`` (``update`` only)."""
    spec = spec_of(mdp, 500_000)
    state = agent.init(key, spec, hp) if state is None else state
    A = int(np.sum(np.asarray(mdp.action_mask)))

    def body(c, k):
        obs, env_state, st = c
        k_a, k_s = jax.random.split(k)
        a = jax.random.randint(k_a, (), 0, A)
        obs2, env_state2, r, term, _, info = jaxmdp.step(k_s, env_state, a, mdp)
        tr = Transition(obs=obs, action=a, reward=r, next_obs=info["final_observation"], h=env_state.h,
                        terminated=term)
        return (obs2, env_state2, agent.update(st, tr)), None

    obs, env_state = jaxmdp.reset(jax.random.fold_in(key, 1), mdp)
    (_, _, state), _ = jax.lax.scan(jax.jit(body), (obs, env_state, state), jax.random.split(key, n_steps))
    return state.replace(plan_due=jnp.ones((), bool))


def warm_state(agent, mdp, hp, play: int, more: int):
    """The agent's state before the plan of its second epoch: ``play`` uniformly random steps, a cold plan, ``more``
    further steps (so that a plan from it is warm-started from the previous epoch's values, as in a run)."""
    state = jax.jit(lambda k: played(agent, mdp, hp, play, k))(jax.random.key(0))
    first = jax.jit(agent.plan)(jax.random.key(1), state)
    return jax.jit(lambda k, st: played(agent, mdp, hp, more, k, st))(jax.random.key(2), first)


def best_of(fn, *args, repeats: int) -> tuple[float, object]:
    out = jax.block_until_ready(fn(*args))  # compile
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - t)
    return best, out


def in_program_seconds(fn, keys, states, *, calls: int = 4, repeats: int = 3) -> float:
    """Seconds of one call ``fn(keys, states)`` (e.g. a ``vmap``-ed plan) inside one compiled program, as the runner
    pays it: ``(t(1 + calls) - t(1)) / calls``, with ``t(m)`` the best of ``repeats`` runs of a loop of ``m`` calls.
    Wall time: on a CPU the program spreads its work over every core it may use, while the runner runs one shard per
    core, so a cost per core needs the process pinned to one (``taskset -c 0``; a posterior draw of episodic PSRL
    at 400 states: 4.5 ms on two cores, 6.7 ms on one; docs/benchmarks/bench_psrl_draw_floor.md).

    A call of its own program costs more on a CPU (PSRL continuous at 948 states: a plan 155 ms per call, 75-85 ms
    in a loop; docs/benchmarks/continuous_planning.md). Likely, not proven: XLA allocates the program's temporary
    buffer (29-92 MB there) at each call, and a buffer that large comes from the system afresh, page by page. The
    runner's plans run inside its chunk programs, which reuse one buffer. Call ``i`` of the loop
    uses ``fold_in(key, i)`` of each key and passes the states through an optimisation barrier with ``i``, so that
    XLA cannot hoist the key-independent work (e.g. a model built from the counts) out of the loop."""
    run_loop = _program_loop(fn)
    times = {m: best_of(run_loop, keys, states, jnp.asarray(m), repeats=repeats)[0] for m in (1, 1 + calls)}
    return max(times[1 + calls] - times[1], 0.0) / calls


@functools.cache
def _program_loop(fn):
    """The jitted loop of ``m`` calls of ``fn`` that :func:`in_program_seconds` times, one per ``fn`` (so that timing
    the same ``fn`` again, e.g. alternating with a baseline, does not compile it again)."""

    def loop(keys, states, m):
        def body(i, acc):
            k, st, _ = jax.lax.optimization_barrier((keys, states, i))
            out = fn(jax.vmap(lambda kk: jax.random.fold_in(kk, i))(k), st)
            return acc + sum(jnp.sum(x.astype(jnp.float32)) for x in jax.tree.leaves(out)
                             if jnp.issubdtype(x.dtype, jnp.floating))

        return jax.lax.fori_loop(0, m, body, jnp.zeros((), jnp.float32))

    return jax.jit(loop)


def profile(agent_name: str, label: str, args) -> dict:
    agent = AGENTS[agent_name]
    inst = sets.instance(args.set, label)
    mdp = inst.build(0)
    S, A = int(np.sum(np.asarray(mdp.state_mask))), int(np.sum(np.asarray(mdp.action_mask)))
    hp = agent.default_hparams
    if agent_name == "psrl_continuous":
        hp = hp.replace(max_psi=pc.psi(hp, S, A))
    key = jax.random.key(0)
    state = jax.jit(lambda k: played(agent, mdp, hp, args.steps, k))(key)
    plan = jax.jit(jax.vmap(agent.plan))
    one = lambda x: jax.tree.map(lambda y: y[None], x)  # noqa: E731
    keys = jax.random.split(jax.random.key(1), 1)
    row = dict(agent=agent_name, mdp=label, S=S, A=A, steps=args.steps)
    cold_s, cold = best_of(plan, keys, one(state), repeats=args.repeats)
    first = jax.tree.map(lambda y: y[0], cold)
    more = jax.jit(lambda k, st: played(agent, mdp, hp, args.more, k, st))(jax.random.key(2), first)
    warm_s, warm = best_of(plan, keys, one(more), repeats=args.repeats)
    it = "plan_iterations" if agent_name == "psrl_continuous" else "evi_iterations"
    row.update(cold_ms=1e3 * cold_s, cold_iterations=int(getattr(cold, it)[0]),
               warm_ms=1e3 * warm_s, warm_iterations=int(getattr(warm, it)[0]))
    if agent_name == "psrl_continuous":
        c = state.constants
        row.update(psi=int(c.psi), eta=float(c.eta),
                   pairs_posterior=int(jnp.sum(state.schedule.visits >= c.eta)))
        draw_s, _ = best_of(jax.jit(jax.vmap(pc.draws)), keys, one(more), repeats=args.repeats)
        rew_s, _ = best_of(jax.jit(jax.vmap(normal_gamma_sample)), keys, one(more.rewards), repeats=args.repeats)
        row.update(candidates_ms=1e3 * draw_s, reward_draw_ms=1e3 * rew_s)
    print(json.dumps(row), flush=True)
    return row


def main(argv=None) -> list[dict]:
    args = build_parser().parse_args(argv)
    labels = args.labels or bucket_labels(args.set)
    rows = [profile(a, lab, args) for a in args.agents for lab in labels]
    if args.out:
        with open(args.out, "w") as f:
            json.dump(rows, f, indent=1)
    return rows


if __name__ == "__main__":
    main()
    sys.exit(0)
