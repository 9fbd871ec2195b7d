"""A minimal lockstep agent/MDP interaction loop for the agents' own tests, written independently of
:mod:`jaxmdp.experiment.runner`: it returns per-step traces (actions, rewards, plan flags) that the runner does not
keep, so the agent tests check each algorithm without going through the runner's chunking, sharding and indicators.

One ``lax.scan`` over time steps drives a batch of agents (leading axis: one key per member) on one MDP shared by
the batch or on a stacked batch of MDPs (one per member, from ``jaxmdp.stack``). Per step:
``act`` -> ``jaxmdp.step`` -> ``update``; then, if *any* member ``needs_plan``, ``plan`` runs for the batch under one
``lax.cond`` and is kept only for the members that asked (the protocol of ``jaxmdp.experiment.agent_interface``). Each
member's randomness is ``fold_in(member_key, t)``, so a member's run does not depend on the rest of the batch.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

import jaxmdp
from jaxmdp.experiment.agent_interface import Agent, Transition, spec_of


class RunResult(NamedTuple):
    state: Any  # final agent states, batched
    actions: jax.Array  # [B, T] (empty [B, 0] unless trace)
    rewards: jax.Array  # [B, T] (empty unless trace)
    planned: jax.Array  # [B, T] whether the member planned after step t (empty unless trace)
    total_reward: jax.Array  # [B]
    n_plans: jax.Array  # [B] plans after the initial one
    n_batch_plans: jax.Array  # [] steps at which the batch ran plan


def _select(mask, new, old):
    return jax.tree.map(lambda n, o: jnp.where(mask.reshape(mask.shape + (1,) * (n.ndim - 1)), n, o), new, old)


def make_runner(
    agent: Agent, n_steps: int, trace: bool = False, plan_chunk: int | None = None, member_hparams: bool = False
):
    """``run(keys[B], mdp, hparams, emissions=None) -> RunResult`` (jitted) for ``n_steps`` interaction steps.

    ``mdp`` is one MDP for every member, or a stacked batch of ``B`` MDPs (member ``i`` faces MDP ``i``).
    ``emissions`` (one MDP only): a noiseless emission table, ``[S, *obs]`` (continuous) or ``[H, S, *obs]``
    (episodic); the agent then observes the table row of the state (and of the in-episode step), not its index, and
    its spec carries the table (the protocol of ``Agent.observation == "emission"``).
    ``member_hparams``: ``hparams`` is stacked, one set per member (a grid over seeds and hyperparameters), instead
    of one set for the whole batch.
    ``plan_chunk``: if given, planning gathers the members that need it into sub-batches of this size (a
    ``while_loop`` over chunks) instead of planning for the whole batch; results are the same, the cost of a plan
    step then scales with the number of members that plan rather than with ``B``.
    """

    def plan_members(states, need, keys):
        B = need.shape[0]
        if plan_chunk is None or plan_chunk >= B:
            return jax.lax.cond(
                jnp.any(need), lambda s: _select(need, jax.vmap(agent.plan)(keys, s), s), lambda s: s, states
            )

        def chunk(carry):
            s, remaining = carry
            idx = jnp.argsort(~remaining, stable=True)[:plan_chunk]  # members still waiting come first
            take = remaining[idx]
            new = jax.vmap(agent.plan)(keys[idx], jax.tree.map(lambda x: x[idx], s))
            s = jax.tree.map(lambda full, n: full.at[idx].set(_select(take, n, full[idx])), s, new)
            return s, remaining.at[idx].set(False)

        return jax.lax.while_loop(lambda c: jnp.any(c[1]), chunk, (states, need))[0]

    def run(keys, mdp, hparams, emissions=None):
        m = 0 if mdp.T.ndim == 4 else None
        spec = spec_of(mdp, n_steps).replace(observations=emissions)

        def observe(s, h):
            if emissions is None:
                return s
            return emissions[h, s] if mdp.episodic else emissions[s]

        k = jax.vmap(lambda key: jax.random.split(key, 4))(keys)
        states = jax.vmap(agent.init, (0, m, 0 if member_hparams else None))(k[:, 0], spec, hparams)
        states = jax.vmap(agent.plan)(k[:, 1], states)
        obs, env = jax.vmap(jaxmdp.reset, (0, m))(k[:, 2], mdp)
        obs = jax.vmap(observe)(obs, env.h)
        loop_keys = k[:, 3]

        def body(carry, t):
            states, env, obs, total, n_plans, n_batch = carry
            kt = jax.vmap(lambda key: jax.random.split(jax.random.fold_in(key, t), 3))(loop_keys)
            a = jax.vmap(agent.act)(kt[:, 0], states, obs, env.h)
            obs_next, env_next, r, term, _, info = jax.vmap(jaxmdp.step, (0, 0, 0, m))(kt[:, 1], env, a, mdp)
            # The state reached is observed at the next in-episode step (the last step of an episode: at h = H - 1,
            # the table's last row, since the episode ends there).
            h_reached = jnp.where(term, env.h, env_next.h) if emissions is not None and mdp.episodic else env_next.h
            final_obs = jax.vmap(observe)(info["final_observation"], h_reached)
            obs_next = jax.vmap(observe)(obs_next, env_next.h)
            tr = Transition(obs=obs, action=a, reward=r, next_obs=final_obs, h=env.h, terminated=term)
            states = jax.vmap(agent.update)(states, tr)
            need = jax.vmap(agent.needs_plan)(states)
            states = plan_members(states, need, kt[:, 2])
            carry = (states, env_next, obs_next, total + r, n_plans + need, n_batch + jnp.any(need))
            return carry, ((a, r, need) if trace else None)

        B = keys.shape[0]
        init = (states, env, obs, jnp.zeros((B,), mdp.dtype), jnp.zeros((B,), jnp.int32), jnp.zeros((), jnp.int32))
        (states, _, _, total, n_plans, n_batch), out = jax.lax.scan(body, init, jnp.arange(n_steps))
        if trace:
            actions, rewards, planned = (x.T for x in out)
        else:
            actions = jnp.zeros((B, 0), jnp.int32)
            rewards = jnp.zeros((B, 0), mdp.dtype)
            planned = jnp.zeros((B, 0), bool)
        return RunResult(states, actions, rewards, planned, total, n_plans, n_batch)

    return jax.jit(run)


def make_grid_runner(agent: Agent, n_steps: int, trace: bool = False):
    """``run(keys[G, B], mdp, hparams[G], emissions=None) -> RunResult`` (jitted) with ``[G, B]`` leading axes: the
    ``G x B`` members (hyperparameter set ``g`` for row ``g``) as one batch of :func:`make_runner`, with one plan
    predicate for the whole batch. (A ``vmap`` over ``G`` of the loop gives the same numbers, but turns its ``cond``s
    into ``select``s and compiles longer: BootDQN's probe runner 21 s against 13 s.)"""
    run = make_runner(agent, n_steps, trace=trace, member_hparams=True)

    def grid_run(keys, mdp, hparams, emissions=None):
        G, B = keys.shape
        member_hparams = jax.tree.map(lambda x: jnp.repeat(x, B, axis=0), hparams)
        result = run(keys.reshape(G * B), mdp, member_hparams, emissions)
        return jax.tree.map(lambda x: x.reshape(G, B, *x.shape[1:]) if x.ndim else x, result)

    return jax.jit(grid_run)


def seeds(n: int, base: int = 0) -> jax.Array:
    """``n`` member keys."""
    return jax.random.split(jax.random.key(base), n)


def grid_seeds(n_groups: int, n: int, base: int = 0) -> jax.Array:
    """``[n_groups, n]`` member keys, all distinct: a grid over hyperparameter sets and seeds whose members are
    independent (the learning tests' binomial failure counts assume it; the same ``n`` keys in every row would make
    the rows' outcomes correlated)."""
    return jax.random.split(jax.random.key(base), n_groups * n).reshape(n_groups, n)


def bandit(means, episodic: bool, H: int = 2, conc: float = 4.0) -> jaxmdp.MDP:
    """A one-state MDP whose actions pay Beta rewards of the given means (``conc`` = alpha + beta)."""
    A = len(means)
    return jaxmdp.custom_mdp(
        np.ones((1, A, 1)),
        P0=[1.0],
        H=H if episodic else None,
        reward_mean=np.asarray(means, np.float64)[None, :, None],
        reward_conc=np.full((1, A, 1), conc),
    )


def probe_mdps(episodic: bool) -> list[jaxmdp.MDP]:
    """Probes with known answers: deterministic RiverSwim 5 (optimal: always RIGHT) three times, then a 3-armed
    bandit (optimal: arm 2). Stacked, the bandit is padded to 5 states and RiverSwim to 3 actions."""
    river = jaxmdp.make("RiverSwim", episodic=episodic, seed=0, size=5, randomize_actions=False)
    return [river, river, river, bandit((0.3, 0.5, 0.8), episodic)]


def probe_batch(episodic: bool, copies: int) -> jaxmdp.MDP:
    """``copies`` copies of :func:`probe_mdps` stacked (``4 copies`` members; member ``i`` is a bandit iff
    ``i % 4 == 3``)."""
    return jaxmdp.stack(probe_mdps(episodic) * copies).strip()


def is_river(n_members: int) -> np.ndarray:
    """Which members of a :func:`probe_batch` face RiverSwim."""
    return np.arange(n_members) % 4 != 3
