"""The lockstep experiment runner: many (MDP, hyperparameters, seed) members in one compiled program.

A run drives a flat batch of ``B`` *members* (a :class:`Grid`), each with its own MDP, hyperparameters and key,
through ``n_steps`` agent/MDP interaction steps (paper §3.3 and App. A.1; docs/measures.md §6.1):

* the time loop is a ``lax.fori_loop`` over the steps between two log points, whose body ``vmap``s ``jaxmdp.step``
  and the agent's ``act``/``update`` over the batch, inside a ``lax.while_loop`` over log points (with the log's
  ``lax.cond`` inside the per-step body, XLA copied the whole carry, policy cache included, at every step);
* planning (``agent.plan``) runs under a ``lax.cond`` whose predicate is unbatched, "some member needs to plan", and
  only the members that asked are planned, ``plan_slots`` at a time (:mod:`jaxmdp.experiment.planning`), so planning
  is paid at boundaries only and for those members only; every member plans before its first action, in the same
  step (the initialisation program holds no plan, so the plan is compiled once less);
* indicator logging (:mod:`jaxmdp.experiment.indicators`, exact policy evaluation of ``agent.policy``, or of
  ``agent.warm_policy`` started from what the member's previous log returned) runs under a
  ``lax.cond`` on "this is a log step" (a chunk may end between two): after every ``log_period`` steps and after
  the last step. A log made after
  ``c`` steps covers the ``k = c - c_prev`` steps since the previous log (the paper's approximation; ``log_period=1``
  is the exact mode): ``cumulative_regret += k r_c`` and likewise for the normalised regret and the expected reward.
  The cumulative (sampled) reward is summed every step. All sums are compensated (Kahan) so that float32 keeps
  its precision over long runs;
* memory is flat in ``n_steps``: the carry holds running sums only, and a run emits a fixed number of records
  (``n_records`` evenly spaced snapshots, the last one after step ``n_steps``);
* ``record_visits=True`` adds an ``[B, S]`` count of the states each member acted in (``RunResult.visits``); it is a
  static setting, so a run without it compiles no counting at all.

The host runs the compiled loop in chunks (:func:`run`), shows progress, appends each chunk's records to a CSV and
can checkpoint the carry so that an interrupted run resumes without losing finished work. Every random draw comes
from the member's key folded with the step index, so a run's results do not depend on how it was chunked or whether
it was resumed. Learning runs for ``n_steps`` steps and compute time is reported beside the results (the reference
instead stops learning after a wall-clock budget, docs/benchmark.md §2). ``stop_when_converged=True`` adds the
reference's other stop (docs/measures.md §6.4): a member whose normalised regret has been near 0 at ten logs in a row
past a fifth of the run stops learning and acts with its agent as it is for the rest of the run.

Step bookkeeping (differs from the reference's off-by-one, docs/measures.md §6.1, which logs at loop index ``t`` with
``t + 1`` steps done but labels and charges ``t``): the record labelled ``steps = c`` is made after exactly ``c``
interaction steps and agent updates, every cumulative quantity covers exactly those ``c`` steps, and the indicator
of a log evaluates the policy estimate after the ``c``-th update.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxmdp import dynamic_programming as dp
from jaxmdp import env
from jaxmdp.gth import band_order
from jaxmdp._checks import VARIANTS, Variant, check_bool, check_int, check_variant
from jaxmdp.experiment.agent_interface import Agent, Transition, batch_bytes, plans_whole, spec_of, where_due
from jaxmdp.experiment.checkpoints import fingerprint, load_checkpoint, save_checkpoint
from jaxmdp.experiment.memory import ProgramTooLarge, check_fits
from jaxmdp.experiment.indicators import (
    AGENT_COLUMNS,
    ITERATIVE_GAIN_GIVE_UP,
    ITERATIVE_GAIN_SWEEPS,
    IndicatorConstants,
    indicator_constants,
    instant_from_values,
    policy_values,
)
from jaxmdp.blockmdp.block_mdp import BlockMDP
from jaxmdp.experiment.planning import default_plan_slots, plan_due
from jaxmdp.experiment.members import Grid, dynamics, grid, member_mdp, n_distinct, product, seed_keys, stack_hparams
from jaxmdp.experiment.records import MEMBER_COLUMNS, RunResult, append_rows, csv_rows, record_steps, truncate_csv
from jaxmdp.mdp import MDP
from jaxmdp.sampling import fused_random

__all__ = [
    "Grid", "grid", "product", "seed_keys", "stack_hparams", "RunResult", "run", "record_steps", "MEMBER_COLUMNS",
    "ProgramTooLarge", "DEFAULT_CHUNKS", "default_chunk_steps", "plan_slots_for",
]


#: The reference's convergence stop (``run(..., stop_when_converged=True)``, docs/measures.md §6.4): past
#: ``1 / CONVERGED_AFTER_DIVISOR`` of the steps (the reference's 0.2, compared in integers), when the last ``CONVERGED_LOGS`` logged normalised regrets are all within the
#: tolerance of 0 (``1e-4`` episodic, ``1e-5`` continuous) and the current one within ``1e-8``, the member stops
#: learning.
CONVERGED_LOGS = 10
CONVERGED_AFTER_DIVISOR = 5
CONVERGED_TOLERANCE = {True: 1e-4, False: 1e-5}  # by MDP.episodic
CONVERGED_CURRENT_TOLERANCE = 1e-8

# Sub-keys of a member's key: environment, actions, planning, initialisation.
_N_SUBKEYS = 4
# Tags of the initialisation sub-key: the reset, the agent's init and the plan before the first action.
_INIT_TAGS = {"reset": 0, "init": 1, "plan": 2}


# ---------------------------------------------------------------------------------------------------------------
# The compiled program
# ---------------------------------------------------------------------------------------------------------------


class Sums(struct.PyTreeNode):
    """Compensated running sums: ``value`` and Kahan ``compensation``."""

    value: jax.Array
    compensation: jax.Array

    @classmethod
    def zeros(cls, shape: tuple[int, ...], dtype: Any) -> "Sums":
        return cls(value=jnp.zeros(shape, dtype), compensation=jnp.zeros(shape, dtype))

    def add(self, x: jax.Array) -> "Sums":
        y = x - self.compensation
        total = self.value + y
        return Sums(value=total, compensation=(total - self.value) - y)


class Carry(struct.PyTreeNode):
    """Everything the time loop carries. ``t``: steps done; ``last_log``: steps at the previous log."""

    t: jax.Array
    last_log: jax.Array
    key_data: jax.Array  # [B, 4, 2]
    env_state: env.EnvState
    observation: jax.Array  # [B, ...] what each agent acts on next: the state, or a BlockMDP's (noisy) observation
    episode_start: jax.Array  # start state of the episode the next action belongs to
    last_start: jax.Array  # start state of the episode of the last action taken
    agent_state: Any
    reward: Sums  # [B] cumulative sampled reward, summed every step
    logged: Sums  # [B, 3] cumulative regret, expected reward and normalised regret, summed at logs
    # [B, ...] the policy evaluated at the previous log (NaN or -1 before the first); [B, 0] for a fixed policy
    policy_cache: jax.Array
    value_cache: jax.Array  # [B, S] its values (V_0 or the gain from every state)
    policy_start: jax.Array  # [B, ...] the next log's warm start of agent.warm_policy, else [B, 0]
    visits: jax.Array  # [B, S] int32 count of the states acted in (record_visits), else [B, 0]
    # stop_when_converged: [B, CONVERGED_LOGS] the normalised regrets of the last logs (inf before), else [B, 0]
    recent_regrets: jax.Array
    # stop_when_converged: [B, 1] int32 the step after which the member stopped learning (0: it learns), else [B, 0]
    stopped_at: jax.Array
    # stop_when_converged: the agent states as they were when the members stopped (what a stopped member acts with
    # and is evaluated on; agent_state goes on learning unseen), else [B, 0]
    frozen_state: Any


class Schedule(struct.PyTreeNode):
    """Traced run settings (so one compiled program serves any ``n_steps`` and periods)."""

    n_steps: jax.Array
    log_period: jax.Array
    record_period: jax.Array


def _keys(key_data: jax.Array, which: int, t: jax.Array) -> jax.Array:
    """Per-member key ``which`` of a member for step ``t`` (vectorised over members)."""
    return fused_random.fold_in(jax.random.wrap_key_data(key_data[:, which]), t)


def _init_keys(key_data: jax.Array, tag: str) -> jax.Array:
    """Per-member initialisation key ``tag`` (:data:`_INIT_TAGS`)."""
    return _keys(key_data, 3, jnp.uint32(_INIT_TAGS[tag]))


def _plan_keys(key_data: jax.Array, t: jax.Array) -> jax.Array:
    """Per-member planning keys before step ``t``'s action: the initialisation's ``plan`` key before the first
    action (``t = 0``), else planning sub-key ``t + 1``."""
    first = jax.random.key_data(_init_keys(key_data, "plan"))
    later = jax.random.key_data(_keys(key_data, 2, t + 1))
    return jax.random.wrap_key_data(jnp.where(t == 0, first, later))


def _evaluate_changed(
    dyn: MDP, mdp_index: jax.Array, policy: jax.Array, changed: jax.Array, cache: jax.Array,
    rows: jax.Array | None = None, orders: jax.Array | None = None, bandwidth: int | None = None,
) -> jax.Array:
    """:func:`policy_values` of the members whose policy ``changed``, ``cache`` for the others.

    ``rows``: the stack's :func:`~jaxmdp.dynamic_programming.successor_rows` (episodic grids of several MDPs), from
    which an episodic evaluation of action indices reads each member's rows by (MDP, state, action).

    On a CPU the members are taken one at a time (``lax.map``) and an unchanged member costs nothing: under ``vmap``
    every member paid for the evaluation (a dense ``O(S^3)`` one when continuous) as soon as one member's policy
    changed, so a grid whose policies change at different times (epochs of UCRL2 and PSRL, Q-learning once its
    greedy policy settles) paid for all members at almost every log (counted on 4-member grids of 20 000 steps: UCRL2
    evaluates 120, 203 and 475 member policies on FrozenLake, SimpleGrid and MiniGridEmpty instead of 296, 528 and
    748; Q-learning's policies change at nearly every log, 781 of 800 on DeepSea). A continuous member's gain is first
    certified on the successor lists (:func:`~jaxmdp.experiment.indicators.policy_values`), the dense solve running
    only when that fails. The bounds start cold (``d_0 = r_pi``): a warm start from the bias estimate of the member's
    previous evaluation certified fewer policies, not more (``scripts/bench_agents.py --quick``, Q-learning
    continuous, MiniGridEmpty, 64 seeds: 0.98 M agent-steps/s warm, 1.64 M cold;
    docs/benchmarks/continuous_indicators.md), and was removed. An agent's action indices (``greedy_actions``) are
    swept on the chosen actions' successor slots only. Vectorising the bounds over the members instead (``vmap``)
    cost 35 times more on Taxi (960 against 27 us an evaluation): the while loops then run as long as the slowest
    member, 128 sweeps whenever one member of the shard does not certify. Elsewhere (GPU) the members stay in
    lockstep with the dense solve.

    ``orders`` (``[B, S]``) and ``bandwidth`` (static): each member's :func:`jaxmdp.gth.band_order`, for the banded
    elimination of the member-by-member dense solve (:func:`_band`; unchecked, as every policy's chain fits them).
    """
    dtype = cache.dtype

    if jax.default_backend() != "cpu" or dyn.episodic:
        # Episodic evaluations are O(H S A K) vectorised passes, like the policy extraction that every member pays
        # anyway; member by member, the loop's per-iteration overhead dominated (H iterations per member and log).
        values = jax.vmap(lambda i, p: policy_values(member_mdp(dyn, i), p, rows=rows, member=i))(mdp_index, policy)
        return jnp.where(changed[:, None], values.astype(dtype), cache)

    def one(args):
        i, p, ch, old, order = args

        def evaluate():
            # The members' own band orders (_band), which every policy's chain fits: no dense branch compiled.
            band = {} if orders is None else dict(order=order, bandwidth=bandwidth, check_band=False)
            return policy_values(member_mdp(dyn, i), p, ITERATIVE_GAIN_SWEEPS, give_up=ITERATIVE_GAIN_GIVE_UP,
                                 **band).astype(dtype)

        return jax.lax.cond(ch, evaluate, lambda: old)

    return jax.lax.map(one, (mdp_index, policy, changed, cache, mdp_index if orders is None else orders))


def _apart(fn: Callable, *args: Any) -> Any:
    """``fn(*args)``, computed apart from the code that uses its result: on CPU inside a ``lax.cond`` whose
    predicate XLA cannot fold (``optimization_barrier(True)``, unbatched under ``vmap``), elsewhere as it is.

    XLA does not fuse a conditional's computations into their users. The runner computes each step's action this
    way when the agent asks (:attr:`~jaxmdp.experiment.agent_interface.Agent.act_apart`). Fused into the step,
    Q-learning's action (its tie-break from the draw's words) went into the fusions that read the tables at the
    action (the optimised HLO of an episodic Taxi run), where it is recomputed for every element they read.
    Q-learning at 1 024 members on the 2-core CPU, indicators every 100 steps: 1.04-1.16x the agent-steps per
    second, the agent's share of an episodic Taxi step 110-114 -> 85-86 ns, with the same results
    (docs/benchmarks/bench_agents_tabular.md). On a GPU a conditional would cost a synchronisation."""
    if jax.default_backend() != "cpu":
        return fn(*args)
    out = jax.eval_shape(fn, *args)
    always = jax.lax.optimization_barrier(jnp.asarray(True))
    zeros = lambda _: jax.tree.map(lambda o: jnp.zeros(o.shape, o.dtype), out)  # noqa: E731
    return jax.lax.cond(always, lambda a: fn(*a), zeros, args)


def _policy_of(agent: Agent) -> Callable:
    """What the indicators evaluate: the agent's ``greedy_actions`` (action indices) where it has them, else its
    ``policy`` (probabilities); the same policy either way."""
    return agent.policy if agent.greedy_actions is None else agent.greedy_actions


# The program builders are cached with a bound (least recently used first out), keyed by the agent (by identity:
# ``Agent`` compares and hashes as an object) and the static settings; ``jax.jit`` caches per input shape below that.
# A cached entry holds its agent, so an agent's identity cannot be reused while its programs are cached.
_MAX_CACHED_PROGRAMS = 32


@functools.lru_cache(maxsize=_MAX_CACHED_PROGRAMS)
def _init_program(
    agent: Agent, record_visits: bool = False, bandwidth: int | None = None, stop_when_converged: bool = False
) -> Callable:
    def init(
        mdps: MDP | BlockMDP, mdp_index: jax.Array, hparams: Any, key_data: jax.Array, n_steps: jax.Array,
        orders: jax.Array | None = None,
    ) -> Carry:
        sub = jax.vmap(lambda k: jax.random.key_data(jax.random.split(jax.random.wrap_key_data(k), _N_SUBKEYS)))(
            key_data
        )
        # The agents' first plan runs in the chunk program's first planning step (t = 0), with the initialisation's
        # "plan" key (_plan_keys): a copy of the plan here compiled it once more (PSRL continuous: 32 -> 23 s for a
        # runner, docs/benchmarks/bench_runner_compile.md).

        # The members' band orders (runner._band), which the indicators use too, go to the agents' specs as a hint
        # for their linear algebra (agents.estimated_model.policy_values).
        def one(i, hp, k_reset, k_init, order):
            m = member_mdp(mdps, i)
            obs, env_state = env.reset(k_reset, m)
            spec = spec_of(m, n_steps, None if orders is None else order, None if orders is None else bandwidth)
            return obs, env_state, agent.init(k_init, spec, hp)

        obs, env_state, state = jax.vmap(one)(
            mdp_index, hparams, _init_keys(sub, "reset"), _init_keys(sub, "init"),
            mdp_index if orders is None else orders,
        )
        B = mdp_index.shape[0]
        policy = jax.eval_shape(jax.vmap(_policy_of(agent)), state)
        dyn = dynamics(mdps)
        return Carry(
            t=jnp.zeros((), jnp.int32),
            last_log=jnp.zeros((), jnp.int32),
            key_data=sub,
            env_state=env_state,
            observation=obs,
            episode_start=env_state.state,
            last_start=env_state.state,
            agent_state=state,
            reward=Sums.zeros((B,), dyn.dtype),
            logged=Sums.zeros((B, 3), dyn.dtype),
            # Before the first log: a value no policy takes (NaN probabilities, action index -1). A fixed policy is
            # never compared, so it keeps no copy.
            policy_cache=jnp.zeros((B, 0), policy.dtype) if agent.fixed_policy
            else jnp.full(policy.shape, -1 if jnp.issubdtype(policy.dtype, jnp.integer) else jnp.nan, policy.dtype),
            value_cache=jnp.zeros((B, dyn.n_states), dyn.dtype),
            policy_start=jnp.zeros((B, 0), dyn.dtype) if agent.warm_policy is None
            else jax.vmap(agent.policy_start)(state),
            visits=jnp.zeros((B, dyn.n_states if record_visits else 0), jnp.int32),
            recent_regrets=jnp.full((B, CONVERGED_LOGS if stop_when_converged else 0), jnp.inf, dyn.dtype),
            stopped_at=jnp.zeros((B, 1 if stop_when_converged else 0), jnp.int32),
            frozen_state=state if stop_when_converged else jnp.zeros((B, 0), dyn.dtype),
        )

    return jax.jit(init)


def plan_slots_for(agent: Agent, states: Any) -> int:
    """Planning slots of a lockstep loop (paper App. A.1) over ``states`` (member axis first; arrays, tracers or
    shapes): ``ceil(B / 16)`` for ``B`` members, on a CPU at most ``agent.plan_slot_bytes // m`` (at least one), ``m``
    one member's state bytes (:func:`~jaxmdp.experiment.planning.default_plan_slots`)."""
    members, nbytes = batch_bytes(states)
    cap = agent.plan_slot_bytes if jax.default_backend() == "cpu" else None
    return default_plan_slots(members, nbytes // max(members, 1), cap)


@functools.lru_cache(maxsize=_MAX_CACHED_PROGRAMS)
def _chunk_program(
    agent: Agent,
    variant: Variant,
    capacity: int,
    n_shards: int,
    carry_treedef: Any,
    record_visits: bool = False,
    plan_slots: int | None = None,
    bandwidth: int | None = None,
    stop_when_converged: bool = False,
) -> Callable:
    """``chunk(carry, mdps, mdp_index, consts, schedule, n) -> (carry, steps[capacity], values[capacity, B, 4],
    n_written)``: ``n`` more steps (traced), recording at most ``capacity`` snapshots.

    ``stop_when_converged`` (static): the reference's convergence stop (:data:`CONVERGED_LOGS`). A member that has
    stopped acts with, and is evaluated on, a copy of its agent state made when it stopped; its live state plans no
    more and is not seen again. (Keeping the live state instead, merged with its update at every step, read and wrote
    the whole state per step: episodic Q-learning ran 4.4 times slower.)

    ``bandwidth``: the members' band orders' (``consts.state_order``, :func:`_band`), for the banded exact gains.

    With ``n_shards > 1`` the members are split over that many local devices with ``shard_map``; each shard runs its
    own loop (its own "some member needs to plan" predicate), so shards never communicate. A grid whose stacked MDPs
    have no Beta reward anywhere (static ``MDP.stochastic_rewards``) compiles no reward draw. ``plan_slots``: members
    planned at once (:func:`jaxmdp.experiment.planning.plan_due`; default :func:`plan_slots_for` a shard); at
    least a shard's members, the whole shard is planned whenever one member asks and the result kept for those that
    did. A shard of more than ``agent.whole_batch_plans`` members, or of more than ``agent.whole_batch_bytes`` bytes
    of agent state, plans in rounds only.
    """

    def chunk(
        carry: Carry, mdps: MDP | BlockMDP, mdp_index: jax.Array, consts: IndicatorConstants, sched: Schedule, n
    ):
        B = mdp_index.shape[0]
        slots = plan_slots_for(agent, carry.agent_state) if plan_slots is None else plan_slots
        dyn = dynamics(mdps)  # the indicators evaluate policies on the states' dynamics
        dtype = dyn.dtype

        def plan_step(c: Carry) -> Carry:
            if not agent.plans:
                return c
            # Before the first action every member plans (the reference's before_start_interacting), later those
            # that ask.
            needs = jax.vmap(agent.needs_plan)(c.agent_state) | (c.t == 0)
            if stop_when_converged:
                needs = needs & (c.stopped_at[:, 0] == 0)
            keys = lambda: _plan_keys(c.key_data, c.t)  # noqa: E731
            if slots >= B:
                do_plan = lambda state: where_due(needs, jax.vmap(agent.plan)(keys(), state), state)  # noqa: E731
            else:
                do_plan = lambda state: plan_due(  # noqa: E731
                    agent.plan, slots, needs, keys(), state, plans_whole(agent, state), lone_rounds=not agent.episodic
                )
            return c.replace(agent_state=jax.lax.cond(jnp.any(needs), do_plan, lambda s: s, c.agent_state))

        # A grid of several plain MDPs steps each member on the stack itself; a BlockMDP grid, or a single MDP (no
        # gather at all), on the member's own MDP.
        stacked = isinstance(mdps, MDP) and n_distinct(mdps) > 1
        # Episodic evaluations on several MDPs read the stack's packed successor rows, built once per chunk.
        rows = dp.successor_rows(dyn) if dyn.episodic and n_distinct(dyn) > 1 else None

        def interact(c: Carry) -> Carry:
            k_env, k_act = _keys(c.key_data, 0, c.t), _keys(c.key_data, 1, c.t)

            def choose(ka, state, obs, h):
                return _apart(agent.act, ka, state, obs, h) if agent.act_apart else agent.act(ka, state, obs, h)

            def one(i, ke, ka, env_state, obs, state, frozen, stopped_at):
                # obs: the state index, or for a BlockMDP the observation sample that step() returned last (so
                # the transition's next_obs is the very sample the agent acts on next, not a second noise draw).
                h = env_state.h
                action = choose(ka, state, obs, h)
                if stop_when_converged:  # a stopped member acts with its frozen state
                    action = jnp.where(stopped_at[0] > 0, choose(ka, frozen, obs, h), action)
                if stacked:  # one gather from the stack per table read (env.step_member)
                    obs2, env_state2, reward, terminated, _, info = env.step_member(ke, env_state, action, mdps, i)
                else:
                    obs2, env_state2, reward, terminated, _, info = env.step(ke, env_state, action, member_mdp(mdps, i))
                tr = Transition(
                    obs=obs, action=action, reward=reward, next_obs=info["final_observation"], h=h,
                    terminated=terminated,
                )
                return obs2, env_state2, agent.update(state, tr), reward, terminated

            obs2, env_state, state, reward, terminated = jax.vmap(one)(
                mdp_index, k_env, k_act, c.env_state, c.observation, c.agent_state, c.frozen_state, c.stopped_at
            )
            visits = c.visits.at[jnp.arange(B), c.env_state.state].add(1) if record_visits else c.visits
            return c.replace(
                visits=visits,
                t=c.t + 1,
                env_state=env_state,
                observation=obs2,
                agent_state=state,
                last_start=c.episode_start,
                episode_start=jnp.where(terminated, env_state.state, c.episode_start),
                reward=c.reward.add(reward.astype(dtype)),
            )

        def changed_policy(c: Carry) -> tuple[jax.Array, jax.Array, jax.Array]:
            """The policy to cache, which members' policies changed since the previous log, and the next log's warm
            start (``agent.warm_policy``: the policy computed from the previous log's)."""
            if agent.fixed_policy:  # evaluated at the first log (the previous log at step 0), never again
                return c.policy_cache, jnp.broadcast_to(c.last_log == 0, (B,)), c.policy_start
            if agent.warm_policy is None:
                policy, start = jax.vmap(_policy_of(agent))(c.agent_state), c.policy_start
            else:
                policy, start = jax.vmap(agent.warm_policy)(c.agent_state, c.policy_start)
            # max over uint8, not any over bool: XLA's CPU reduction of a predicate is about 9x slower (a float
            # [B, H, S, A] policy of Taxi at 512 members: 1.0 us against 0.11 us per agent-step). Reduced over the
            # trailing axes as they are: flattened first (reshape(B, -1)), the comparison fused with the greedy
            # extraction ran 14 times slower (episodic Q-learning, MiniGridEmpty, 512 members: 15.4 ms a log
            # against 1.1 ms, CPU time).
            changed = jnp.max((policy != c.policy_cache).astype(jnp.uint8), axis=tuple(range(1, policy.ndim))) > 0
            return policy, changed, start

        def log(c: Carry) -> tuple:
            # The fields a log writes (logged_fields' order). Policy evaluation is the expensive half of an
            # indicator; a member whose policy is unchanged since the previous log reuses its values (exactly: they
            # cover every state), and the evaluation is skipped altogether when no member's policy changed.
            live = c.agent_state
            if stop_when_converged:  # a stopped member is evaluated on its frozen state
                c = c.replace(agent_state=where_due(c.stopped_at[:, 0] == 0, live, c.frozen_state))
            policy, changed, start = changed_policy(c)

            def evaluate(cache: jax.Array) -> jax.Array:
                current = jax.vmap(_policy_of(agent))(c.agent_state) if agent.fixed_policy else policy
                return _evaluate_changed(dyn, mdp_index, current, changed, cache, rows, consts.state_order, bandwidth)

            values = jax.lax.cond(jnp.any(changed), evaluate, lambda cache: cache, c.value_cache)
            inst = jax.vmap(lambda i, k, v, s, s0: instant_from_values(member_mdp(dyn, i), k, v, s, s0, variant))(
                mdp_index, consts, values, c.env_state.state, c.last_start
            )
            k = (c.t - c.last_log).astype(dtype)
            x = jnp.stack([inst.regret, inst.expected_reward, inst.normalized_regret], axis=-1) * k
            recent, stopped_at, frozen = c.recent_regrets, c.stopped_at, c.frozen_state
            if stop_when_converged:
                r = inst.normalized_regret.astype(dtype)
                recent = jnp.concatenate([recent[:, 1:], r[:, None]], axis=1)
                converged = (
                    (c.t * CONVERGED_AFTER_DIVISOR > sched.n_steps)
                    & jnp.all(jnp.abs(recent) <= CONVERGED_TOLERANCE[dyn.episodic], axis=1)
                    & (jnp.abs(r) <= CONVERGED_CURRENT_TOLERANCE)
                )
                stopping = (stopped_at[:, 0] == 0) & converged
                stopped_at = jnp.where(stopping[:, None], c.t, stopped_at)
                frozen = where_due(stopping, live, frozen)
            return policy, values, c.logged.add(x.astype(dtype)), c.t, start, recent, stopped_at, frozen

        def logged_fields(c: Carry) -> tuple:
            return (c.policy_cache, c.value_cache, c.logged, c.last_log, c.policy_start, c.recent_regrets,
                    c.stopped_at, c.frozen_state)

        t_end = carry.t + n

        def segment(loop):
            # The steps up to the next log point (or the chunk's end) run in a loop of their own: a per-step cond
            # over the whole carry made XLA copy the [B, H, S, A] policy cache at every step.
            c, steps, values, j = loop
            next_log = jnp.minimum((c.t // sched.log_period + 1) * sched.log_period, sched.n_steps)
            c = jax.lax.fori_loop(0, jnp.minimum(next_log, t_end) - c.t, lambda _, c: interact(plan_step(c)), c)
            is_log = (c.t % sched.log_period == 0) | (c.t == sched.n_steps)
            # Only what a log writes leaves the cond: with the whole carry as its result, XLA copied the agent
            # tables at every log.
            policy_cache, value_cache, logged, last_log, start, recent, stopped_at, frozen = jax.lax.cond(
                is_log, log, logged_fields, c
            )
            c = c.replace(policy_cache=policy_cache, value_cache=value_cache, logged=logged, last_log=last_log,
                          policy_start=start, recent_regrets=recent, stopped_at=stopped_at, frozen_state=frozen)
            is_record = (c.t % sched.record_period == 0) | (c.t == sched.n_steps)

            def record(args):
                steps, values, j = args
                # The order of AGENT_COLUMNS: regret, reward, expected reward, normalised regret.
                logged = c.logged.value
                row = [logged[:, 0], c.reward.value, logged[:, 1], logged[:, 2]]
                row = jnp.stack(row + [x.astype(dtype) for x in _diagnostic_values(agent, c.agent_state)], axis=-1)
                return steps.at[j].set(c.t), values.at[j].set(row), j + 1

            steps, values, j = jax.lax.cond(is_record, record, lambda a: a, (steps, values, j))
            return c, steps, values, j

        steps0 = jnp.zeros((capacity,), jnp.int32)
        values0 = jnp.zeros((capacity, B, len(AGENT_COLUMNS) + len(diagnostic_names(agent, carry.agent_state))), dtype)
        init = (carry, steps0, values0, jnp.zeros((), jnp.int32))
        return jax.lax.while_loop(lambda loop: loop[0].t < t_end, segment, init)

    if n_shards == 1:
        return jax.jit(chunk, donate_argnums=0)
    P = jax.sharding.PartitionSpec
    mesh = jax.sharding.Mesh(np.asarray(jax.local_devices()[:n_shards]), ("members",))
    # Per-member leaves carry the member axis first; the scalars (step counters) are the same on every shard.
    carry_specs = jax.tree.unflatten(carry_treedef[0], [P() if nd == 0 else P("members") for nd in carry_treedef[1]])
    in_specs = (carry_specs, P(), P("members"), P("members"), P(), P())
    out_specs = (carry_specs, P(), P(None, "members"), P())
    sharded = jax.shard_map(chunk, mesh=mesh, in_specs=in_specs, out_specs=out_specs, check_vma=False)
    return jax.jit(sharded, donate_argnums=0)


def diagnostic_names(agent: Agent, agent_states: Any) -> tuple[str, ...]:
    """The names of ``agent.diagnostics`` (sorted; none without it) for batched ``agent_states`` (or their shapes)."""
    if agent.diagnostics is None:
        return ()
    return tuple(sorted(jax.eval_shape(jax.vmap(agent.diagnostics), agent_states)))


def _diagnostic_values(agent: Agent, agent_states: Any) -> list[jax.Array]:
    """``[B]`` arrays of the diagnostics of batched ``agent_states``, in :func:`diagnostic_names` order."""
    if agent.diagnostics is None:
        return []
    d = jax.vmap(agent.diagnostics)(agent_states)
    return [d[name] for name in sorted(d)]


def _warn_diagnostics(agent: Agent, agent_states: Any) -> None:
    """A warning per non-zero diagnostic at the end of a run: the agent, the total and how many members."""
    for name, x in zip(diagnostic_names(agent, agent_states), _diagnostic_values(agent, agent_states)):
        x = np.asarray(x)
        if np.any(x != 0):
            warnings.warn(
                f"{agent.name}: {name} = {int(x.sum())} over the run ({int(np.sum(x != 0))} of {x.size} members); "
                f"see the '{name}' column of the records",
                RuntimeWarning,
                stacklevel=3,
            )


@functools.lru_cache(maxsize=len(VARIANTS))
def _constants_program(variant: Variant) -> Callable:
    # lax.map, not vmap: the constants come from planning loops run to convergence, and a vmapped while_loop runs
    # until its slowest member converges. The per-member gather is in the same program.
    def constants(mdps, mdp_index):
        unique = jax.lax.map(lambda m: indicator_constants(dynamics(m), variant), mdps)
        return jax.tree.map(lambda x: x[mdp_index], unique)

    return jax.jit(constants)


# ---------------------------------------------------------------------------------------------------------------
# Host driver: validation, compilation, start or resume, the chunk loop
# ---------------------------------------------------------------------------------------------------------------


def _n_shards(n_members: int, shards: int | None) -> int:
    available = jax.local_device_count()
    if shards is None:
        return max(d for d in range(1, available + 1) if n_members % d == 0)
    shards = check_int("shards", shards)
    if shards > available or n_members % shards:
        raise ValueError(f"shards must divide the {n_members} members and be at most the {available} local devices; "
                         f"got {shards}")
    return shards


def _validate(agent: Agent, g: Grid, variant: str) -> None:
    if not isinstance(agent, Agent):
        raise ValueError(f"agent must be a jaxmdp.experiment.agent_interface.Agent; got {type(agent).__name__}")
    for field in ("whole_batch_plans", "whole_batch_bytes", "plan_slot_bytes"):
        if getattr(agent, field) is not None:
            check_int(f"Agent.{field}", getattr(agent, field), 0, context=f" or None (agent {agent.name!r})")
    if not isinstance(g, Grid):
        raise ValueError("grid must be a jaxmdp.experiment.runner.Grid (see runner.grid and runner.product)")
    check_variant(variant)
    if agent.episodic != g.episodic:
        kind = lambda e: "episodic" if e else "continuous"  # noqa: E731
        raise ValueError(
            f"agent {agent.name!r} is {kind(agent.episodic)} but the MDPs are {kind(g.episodic)}; use a "
            f"{kind(g.episodic)} agent"
        )
    block = isinstance(g.mdps, BlockMDP)
    if agent.observation == "state" and block:
        raise ValueError(
            f"agent {agent.name!r} is tabular: it observes state indices and cannot act on a BlockMDP's emissions "
            "(as in the reference); pass the plain MDPs (block.mdp), or use a deep agent"
        )
    if agent.observation == "emission" and not block:
        raise ValueError(
            f"agent {agent.name!r} is a deep agent: it observes emissions, not state indices; build its grid from "
            "BlockMDPs, e.g. runner.product([jaxmdp.block_mdp(mdp, 'state_info')], ...) (any emission kind of "
            "jaxmdp.EMISSION_KINDS)"
        )
    agent.check_hparams(g.hparams)


def _check_shapes(agent: Agent, g: Grid, n_steps: int) -> None:
    """Abstract evaluation (no compilation) of one member: the agent's policy and action must fit the MDP."""

    def first_member(mdps, hparams):
        # Everything, member 0 included, under eval_shape: an eager slice would compile a program per array.
        m, hp, key = member_mdp(mdps, 0), jax.tree.map(lambda x: x[0], hparams), jax.random.key(0)
        state = agent.init(key, spec_of(m, n_steps), hp)
        obs, _ = env.reset(key, m)
        greedy = agent.greedy_actions(state) if agent.greedy_actions is not None else None
        warm = None
        if agent.warm_policy is not None:
            start = agent.policy_start(state)
            warm = (start, *agent.warm_policy(state, start))
        return agent.policy(state), agent.act(key, state, obs, jnp.zeros((), jnp.int32)), greedy, warm

    m = jax.eval_shape(lambda mdps: member_mdp(mdps, 0), g.mdps)
    S, A, H = m.n_states, m.n_actions, m.H
    try:
        policy, action, greedy, warm = jax.eval_shape(first_member, g.mdps, g.hparams)
    except (TypeError, ValueError, IndexError) as err:
        raise ValueError(f"agent {agent.name!r} does not fit MDPs with S={S}, A={A}, H={H}: {err}") from err
    allowed = [(H, S, A), (S, A)] if H is not None else [(S, A)]
    if policy.shape not in allowed:
        raise ValueError(
            f"agent {agent.name!r} returns a policy of shape {policy.shape} for MDPs with S={S}, A={A}"
            f"{f', H={H}' if H else ''}; expected one of {allowed}"
        )
    if greedy is not None and (greedy.shape != policy.shape[:-1] or not jnp.issubdtype(greedy.dtype, jnp.integer)):
        raise ValueError(
            f"agent {agent.name!r} returns greedy_actions of shape {greedy.shape} {greedy.dtype}; expected integer "
            f"action indices of shape {policy.shape[:-1]} (its policy's shape without the action axis)"
        )
    if action.shape != () or not jnp.issubdtype(action.dtype, jnp.integer):
        raise ValueError(f"agent {agent.name!r} must return one integer action; got {action.shape} {action.dtype}")
    if warm is not None:
        start, warm_policy, start2 = warm
        if (warm_policy.shape, warm_policy.dtype) != (policy.shape, policy.dtype):
            raise ValueError(f"agent {agent.name!r} returns a warm_policy of {warm_policy.shape} {warm_policy.dtype}; "
                             f"expected its policy's {policy.shape} {policy.dtype}")
        if (start2.shape, start2.dtype) != (start.shape, start.dtype):
            raise ValueError(f"agent {agent.name!r}: warm_policy returns a start of {start2.shape} {start2.dtype}; "
                             f"expected policy_start's {start.shape} {start.dtype} (the runner carries it)")


def _final_states(carry: Carry, stop_when_converged: bool) -> Any:
    """The members' agent states at the end of a run (numpy): for a member that stopped learning, its frozen state."""
    states = carry.agent_state
    if stop_when_converged:
        states = where_due(carry.stopped_at[:, 0] == 0, states, carry.frozen_state)
    return jax.tree.map(np.asarray, states)


def _progress(done: int, total: int, elapsed: float, members: int) -> None:
    rate = done * members / elapsed if elapsed > 0 else float("nan")
    print(f"\r  {done}/{total} steps ({100 * done / total:5.1f}%), {rate / 1e6:.2f} M agent-steps/s", end="",
          file=sys.stderr, flush=True)


@dataclasses.dataclass(frozen=True)
class _Settings:
    """A run's validated settings (host side)."""

    n_steps: int
    log_period: int
    record_period: int
    chunk_steps: int
    capacity: int
    n_shards: int
    variant: Variant
    record_visits: bool = False
    plan_slots: int | None = None
    memory_limit: int | None = None
    stop_when_converged: bool = False


@dataclasses.dataclass
class _Program:
    """A run's compiled programs and their (device) inputs."""

    init: Callable
    chunk: Callable
    carry_shape: Any
    mdps: MDP
    mdp_index: jax.Array
    hparams: Any
    key_data: jax.Array
    consts: IndicatorConstants
    sched: Schedule
    compile_s: float
    diagnostic_names: tuple[str, ...] = ()


@dataclasses.dataclass
class _Progress:
    """Where a run stands: the loop's carry, the records so far and the run seconds of earlier sessions."""

    carry: Carry
    steps: np.ndarray
    values: np.ndarray
    elapsed_before: float


#: Chunks of a run when ``chunk_steps`` is not given: the host writes records and a checkpoint after each.
DEFAULT_CHUNKS = 20


def default_chunk_steps(n_steps: int, record_period: int) -> int:
    """Steps per chunk of :func:`run` when ``chunk_steps`` is not given: ``n_steps / DEFAULT_CHUNKS`` rounded up, at
    least one record period (so a short run has fewer chunks), at most ``n_steps``."""
    return min(max(record_period, -(-n_steps // DEFAULT_CHUNKS)), n_steps)


def _validated_settings(
    agent: Agent,
    grid: Grid,
    n_steps: int,
    log_period: int,
    n_records: int,
    variant: str,
    chunk_steps: int | None,
    shards: int | None,
    record_visits: bool = False,
    plan_slots: int | None = None,
    memory_limit: int | None = None,
    stop_when_converged: bool = False,
) -> _Settings:
    """Check every argument on the host, before anything compiles, and derive the chunking (see :func:`run`)."""
    n_steps = check_int("n_steps", n_steps)
    log_period = check_int("log_period", log_period)
    n_records = check_int("n_records", n_records)
    if chunk_steps is not None:
        chunk_steps = check_int("chunk_steps", chunk_steps)
    if plan_slots is not None:
        plan_slots = check_int("plan_slots", plan_slots)
    if memory_limit is not None:
        memory_limit = check_int("memory_limit", memory_limit)
    record_visits = check_bool("record_visits", record_visits)
    stop_when_converged = check_bool("stop_when_converged", stop_when_converged)
    if n_steps >= 2**31 - 1:
        raise ValueError(f"n_steps must be below 2**31 - 1; got {n_steps}")
    _validate(agent, grid, variant)
    n_shards = _n_shards(grid.n_members, shards)
    _check_shapes(agent, grid, n_steps)
    record_period, _ = record_steps(n_steps, log_period, n_records)
    chunk_steps = min(default_chunk_steps(n_steps, record_period) if chunk_steps is None else chunk_steps, n_steps)
    return _Settings(
        n_steps=n_steps,
        log_period=log_period,
        record_period=record_period,
        chunk_steps=chunk_steps,
        capacity=chunk_steps // record_period + 2,
        n_shards=n_shards,
        variant=variant,
        record_visits=record_visits,
        plan_slots=plan_slots,
        memory_limit=memory_limit,
        stop_when_converged=stop_when_converged,
    )


#: Fewest states for which the runner eliminates on a band (:func:`_band`). Below it the dense elimination costs about
#: the same (continuous RiverSwim, 30 states: 0.18 against 0.19 ms an evaluation; 80 states: 1.0 against 0.37 ms),
#: and a banded fallback costs 0.5-0.9 s more to compile per runner (docs/benchmarks/continuous_indicators.md).
BAND_MIN_STATES = 64


def _band(mdps: MDP | BlockMDP, mdp_index: np.ndarray) -> tuple[jax.Array | None, int | None]:
    """Each member's band order (``[B, S]``) and their bandwidth (:func:`jaxmdp.gth.band_order`, host side) when the
    exact continuous gains are taken member by member (a CPU), the MDPs have at least :data:`BAND_MIN_STATES` states
    and the band is under half of them; else ``(None, None)``: under ``vmap`` (GPU) the banded and dense eliminations
    would both run."""
    dyn = dynamics(mdps)
    if dyn.episodic or jax.default_backend() != "cpu" or dyn.n_states < BAND_MIN_STATES:
        return None, None
    order, width = band_order(dyn)
    if 2 * width >= dyn.n_states:
        return None, None
    order = order.reshape(-1, dyn.n_states)
    return jax.device_put(order[np.asarray(mdp_index) if len(order) > 1 else np.zeros(len(mdp_index), int)]), width


def _compile(agent: Agent, grid: Grid, settings: _Settings) -> _Program:
    """Compute the indicator constants and compile the initialisation and chunk programs (timed together); raise
    :class:`~jaxmdp.experiment.memory.ProgramTooLarge` before anything runs if one of them would not fit in memory."""
    mdps = grid.mdps
    # device_put, not jnp.asarray, which compiles a small program per array shape.
    mdp_index = jax.device_put(grid.mdp_index)
    hparams = jax.tree.map(jax.device_put, grid.hparams)
    key_data = jax.device_put(grid.key_data)
    sched = Schedule(
        n_steps=jnp.asarray(settings.n_steps, jnp.int32),
        log_period=jnp.asarray(settings.log_period, jnp.int32),
        record_period=jnp.asarray(settings.record_period, jnp.int32),
    )
    t0 = time.perf_counter()
    consts = _constants_program(settings.variant)(mdps, mdp_index)
    orders, bandwidth = _band(mdps, grid.mdp_index)
    consts = consts.replace(state_order=orders)
    init_jit = _init_program(agent, settings.record_visits, bandwidth, settings.stop_when_converged)
    init_fn = init_jit.lower(mdps, mdp_index, hparams, key_data, sched.n_steps, orders).compile()
    carry_shape = jax.eval_shape(init_jit, mdps, mdp_index, hparams, key_data, sched.n_steps, orders)
    leaves, treedef = jax.tree.flatten(carry_shape)
    carry_layout = (treedef, tuple(x.ndim for x in leaves))
    chunk_fn = _chunk_program(
        agent, settings.variant, settings.capacity, settings.n_shards, carry_layout, settings.record_visits,
        settings.plan_slots, bandwidth, settings.stop_when_converged,
    )
    chunk_exe = chunk_fn.lower(carry_shape, mdps, mdp_index, consts, sched, jnp.int32(0)).compile()
    jax.block_until_ready(consts)
    check_fits(
        [("initialisation", init_fn), ("chunk", chunk_exe)],
        settings.n_shards,
        limit=settings.memory_limit,
        remedy=f"run fewer than its {grid.n_members} members per call (split the grid)" if grid.n_members > 1
        else "a single member: it needs a machine with more memory",
    )
    return _Program(
        init=init_fn, chunk=chunk_exe, carry_shape=carry_shape, mdps=mdps, mdp_index=mdp_index, hparams=hparams,
        key_data=key_data, consts=consts, sched=sched, compile_s=time.perf_counter() - t0,
        diagnostic_names=diagnostic_names(agent, carry_shape.agent_state),
    )


def _start_or_resume(
    program: _Program, n_members: int, run_id: str, ckpt: Path | None, csv_file: Path | None, resume: bool
) -> _Progress:
    """Continue this run's checkpoint if there is one (and ``resume``), dropping CSV rows written after it;
    otherwise initialise every member and start a fresh CSV."""
    if ckpt is not None and resume and ckpt.exists():
        carry, steps_done, values_done, meta = load_checkpoint(ckpt, program.carry_shape, run_id)
        if csv_file is not None:
            truncate_csv(csv_file, int(carry.t), program.diagnostic_names)
        return _Progress(carry, steps_done, values_done, float(meta["run_s"]))
    carry = program.init(program.mdps, program.mdp_index, program.hparams, program.key_data, program.sched.n_steps,
                         program.consts.state_order)
    jax.block_until_ready(carry)
    if csv_file is not None:
        csv_file.parent.mkdir(parents=True, exist_ok=True)
        truncate_csv(csv_file, -1, program.diagnostic_names)
    steps_done = np.zeros((0,), np.int64)
    n_columns = len(AGENT_COLUMNS) + len(program.diagnostic_names)
    values_done = np.zeros((0, n_members, n_columns), np.dtype(dynamics(program.mdps).dtype))
    return _Progress(carry, steps_done, values_done, 0.0)


def _run_chunks(
    agent: Agent,
    grid: Grid,
    program: _Program,
    start: _Progress,
    settings: _Settings,
    run_id: str,
    ckpt: Path | None,
    csv_file: Path | None,
    progress: bool,
    stop_after_chunks: int | None,
) -> tuple[_Progress, float]:
    """Run the chunk program until ``n_steps`` (or ``stop_after_chunks``), appending each chunk's records to the CSV
    and checkpointing after each; returns where the run stands and its run seconds over every session."""
    n_steps = settings.n_steps
    carry, steps_done, values_done = start.carry, start.steps, start.values
    consts_np = jax.tree.map(np.asarray, program.consts)
    t_start = time.perf_counter()
    chunks = 0
    while int(carry.t) < n_steps:
        n = min(settings.chunk_steps, n_steps - int(carry.t))
        carry, steps, values, j = program.chunk(
            carry, program.mdps, program.mdp_index, program.consts, program.sched, jnp.int32(n)
        )
        j = int(j)
        steps, values = np.asarray(steps)[:j], np.asarray(values)[:j]
        elapsed = start.elapsed_before + time.perf_counter() - t_start
        steps_done = np.concatenate([steps_done, steps])
        values_done = np.concatenate([values_done, values])
        if csv_file is not None and j:
            per_second = np.full((j,), int(carry.t) / elapsed)
            append_rows(csv_file, csv_rows(grid, steps, values, consts_np, per_second))
        if ckpt is not None:
            meta = {"fingerprint": run_id, "run_s": elapsed, "t": int(carry.t), "agent": agent.name}
            save_checkpoint(ckpt, carry, steps_done, values_done, meta)
        if progress:
            _progress(int(carry.t), n_steps, elapsed, grid.n_members)
        chunks += 1
        if stop_after_chunks is not None and chunks >= stop_after_chunks and int(carry.t) < n_steps:
            break
    if progress:
        print(file=sys.stderr)
    run_s = start.elapsed_before + time.perf_counter() - t_start
    return _Progress(carry, steps_done, values_done, start.elapsed_before), run_s


def run(
    agent: Agent,
    grid: Grid,
    n_steps: int,
    *,
    log_period: int = 100,
    n_records: int = 100,
    variant: Variant = "paper",
    chunk_steps: int | None = None,
    csv_path: str | os.PathLike | None = None,
    checkpoint_path: str | os.PathLike | None = None,
    resume: bool = True,
    progress: bool = False,
    stop_after_chunks: int | None = None,
    shards: int | None = None,
    record_visits: bool = False,
    plan_slots: int | None = None,
    memory_limit: int | None = None,
    stop_when_converged: bool = False,
) -> RunResult:
    """Run ``agent`` on every member of ``grid`` for ``n_steps`` steps in lockstep (see the module docstring).

    Args:
      agent: the agent (see :mod:`jaxmdp.experiment.agent_interface`).
      grid: the members (:func:`grid` or :func:`product`).
      n_steps: interaction steps per member (the optimisation horizon ``T`` given to the agent).
      log_period: steps between indicator logs (the reference's ``log_performance_indicators_every``, 100);
        ``1`` is the exact mode.
      n_records: at most this many snapshots per member (:func:`record_steps`); memory does not grow with
        ``n_steps``.
      variant: ``"paper"`` (default) or ``"colosseum"`` indicators (:mod:`jaxmdp.experiment.indicators`).
      chunk_steps: steps per host-side chunk (default: about 20 chunks, at least one record period each).
      csv_path: append each chunk's records to this CSV (``member, mdp, hparams, seed`` + the reference's columns).
      checkpoint_path: save the loop's state after each chunk (``.npz``); with ``resume=True`` an existing
        checkpoint of the same run is continued (records already written are kept).
      progress: print progress to stderr.
      stop_after_chunks: stop after this many chunks of this call (to test interruption; the result then holds the
        records so far).
      shards: split the members over this many local devices (default: as many as divide the batch, up to
        ``jax.local_device_count()``). XLA runs one lockstep loop on one core; to use every core of a CPU, start
        Python with ``XLA_FLAGS=--xla_force_host_platform_device_count=<cores>`` (before JAX is imported).
      record_visits: also count, per member, the states it took its actions in (``RunResult.visits``, ``[B, S]``
        int, summing to ``n_steps`` per member; for a BlockMDP the latent states). Off by default: the loop then
        carries and computes nothing for it.
      plan_slots: members planned at once when some members of a lockstep loop (a shard) need a plan
        (:mod:`jaxmdp.experiment.planning`): rounds of this many until all are served, so planning costs in
        proportion to the members that asked; default ``ceil(members / 16)`` per shard, on a CPU at most
        ``agent.plan_slot_bytes`` of agent state a round (:func:`plan_slots_for`). A value at least a shard's
        members plans the whole shard whenever one member asks (the earlier scheme). The results do not depend on it.
      memory_limit: bytes the compiled programs may need (all shards together on a CPU, per device on an
        accelerator); default what the devices have available (:mod:`jaxmdp.experiment.memory`).
      stop_when_converged: the reference's convergence stop (docs/measures.md §6.4, [quirk]): a member stops
        learning (it acts with, and is evaluated on, its agent state as it is; ``RunResult.agent_state`` holds
        that state) at the first log past
        ``1 /`` :data:`CONVERGED_AFTER_DIVISOR` of the steps where its last :data:`CONVERGED_LOGS` normalised regrets are within
        :data:`CONVERGED_TOLERANCE` of 0 and the current one within :data:`CONVERGED_CURRENT_TOLERANCE`. Its later
        logs evaluate that agent state's policy as before (the reference computes its regret once and reuses it).
        ``RunResult.stopped_at`` tells when. The loop then holds each member's agent state twice (live and frozen)
        and computes each action twice. Off by default: the paper's protocol learns to the end.

    Raises:
      ValueError: before anything compiles, for an episodic agent on continuous MDPs (or the reverse), an agent
        whose policy or action does not fit the MDPs' ``S``/``A``/``H``, non-positive ``n_steps``, ``log_period`` or
        ``n_records``, hyperparameters outside their domain (``agent.check_hparams``), an ``agent.whole_batch_plans``
        or ``agent.whole_batch_bytes`` that is neither ``None`` nor an integer >= 0, or a checkpoint of another run.
      ProgramTooLarge: after compiling, before anything runs, when a program needs more memory than
        ``memory_limit`` (a ``MemoryError``; split the members over several calls).
    """
    settings = _validated_settings(
        agent, grid, n_steps, log_period, n_records, variant, chunk_steps, shards, record_visits, plan_slots,
        memory_limit, stop_when_converged,
    )
    program = _compile(agent, grid, settings)
    run_id = fingerprint(agent.name, grid, settings.n_steps, settings.log_period, settings.record_period, variant)
    if record_visits:  # a checkpoint of a run without counts cannot continue one with them (and vice versa)
        run_id += "+visits"
    if stop_when_converged:
        run_id += "+converged-stop"
    ckpt = Path(checkpoint_path) if checkpoint_path is not None else None
    csv_file = Path(csv_path) if csv_path is not None else None
    start = _start_or_resume(program, grid.n_members, run_id, ckpt, csv_file, resume)
    done, run_s = _run_chunks(
        agent, grid, program, start, settings, run_id, ckpt, csv_file, progress, stop_after_chunks
    )
    _warn_diagnostics(agent, done.carry.agent_state)
    return RunResult(
        steps=done.steps,
        values=done.values,
        constants=jax.tree.map(np.asarray, program.consts),
        grid=grid,
        agent=agent.name,
        compile_s=program.compile_s,
        run_s=run_s,
        n_steps=settings.n_steps,
        log_period=settings.log_period,
        record_period=settings.record_period,
        variant=variant,
        agent_state=_final_states(done.carry, stop_when_converged),
        visits=np.asarray(done.carry.visits) if record_visits else None,
        stopped_at=np.asarray(done.carry.stopped_at[:, 0]) if stop_when_converged else None,
        diagnostic_names=program.diagnostic_names,
    )
