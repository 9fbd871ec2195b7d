"""The lockstep loop of the runner as pure functions: the carry, one step (plan, then interact), a log and a record.

A chunk of a run (:func:`chunk`) is a ``lax.while_loop`` over *segments*, the steps from one log point to the next
(or to the chunk's end). A segment runs its steps in a ``lax.fori_loop`` whose body is :func:`step`
(:func:`plan_step` then :func:`interact`, both ``vmap``-ed over the members), then :func:`log` under a ``lax.cond``
on "this is a log step", then :func:`record` under a ``lax.cond`` on "this is a record step" (paper §3.3, App. A.1;
the design and bookkeeping are stated in :mod:`jaxmdp.experiment.runner`). Every function here is traced inside the
program that :mod:`jaxmdp.experiment.programs` compiles; the static settings of that program are a :class:`Loop`
and what every step of a chunk reads but none writes is a :class:`Fixed`.

The reference's convergence stop (``Loop.stop_when_converged``, docs/measures.md §6.4) touches three places, each a
named function here: a stopped member asks for no plan (:func:`plan_step`), acts with the agent state it had when it
stopped (:func:`interact`) and is evaluated on that state (:func:`evaluated_states`); :func:`converged` decides at
each log who stops.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

from jaxmdp import dynamic_programming as dp
from jaxmdp import env
from jaxmdp import struct
from jaxmdp._checks import Variant
from jaxmdp.blockmdp.block_mdp import BlockMDP
from jaxmdp.experiment import indicators
from jaxmdp.experiment.agent_interface import Agent, Transition, batch_bytes, plans_whole, spec_of, where_due
from jaxmdp.experiment.indicators import AGENT_COLUMNS, IndicatorConstants, instant_from_values, policy_values
from jaxmdp.experiment.members import dynamics, member_mdp, n_distinct
from jaxmdp.experiment.planning import default_plan_slots, plan_due
from jaxmdp.mdp import MDP
from jaxmdp.sampling import fused_random

__all__ = [
    "Sums", "Carry", "Schedule", "Loop", "Fixed", "init_carry", "step", "plan_step", "interact", "log", "record",
    "segment", "chunk", "evaluate_changed", "apart", "policy_of", "plan_slots_for", "diagnostic_names",
    "CONVERGED_LOGS", "CONVERGED_AFTER_DIVISOR", "CONVERGED_TOLERANCE", "CONVERGED_CURRENT_TOLERANCE",
]

#: The reference's convergence stop (``run(..., stop_when_converged=True)``, docs/measures.md §6.4): past
#: ``1 / CONVERGED_AFTER_DIVISOR`` of the steps (the reference's 0.2, compared in integers), when the last
#: ``CONVERGED_LOGS`` logged normalised regrets are all within the tolerance of 0 (``1e-4`` episodic, ``1e-5``
#: continuous) and the current one within ``1e-8``, the member stops learning.
CONVERGED_LOGS = 10
CONVERGED_AFTER_DIVISOR = 5
CONVERGED_TOLERANCE = {True: 1e-4, False: 1e-5}  # by MDP.episodic
CONVERGED_CURRENT_TOLERANCE = 1e-8

# Sub-keys of a member's key: environment, actions, planning, initialisation.
N_SUBKEYS = 4
# Tags of the initialisation sub-key: the reset, the agent's init and the plan before the first action.
INIT_TAGS = {"reset": 0, "init": 1, "plan": 2}


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
    policy_start: jax.Array  # [B, ...] the next log's warm start of hints.warm_policy, else [B, 0]
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


@dataclasses.dataclass(frozen=True)
class Loop:
    """The static settings of a lockstep loop (what its program is compiled for; see :func:`chunk`).

    ``plan_slots``: members planned at once (``None``: :func:`plan_slots_for` the loop's batch); ``bandwidth``: the
    members' band orders' (``Fixed.consts.state_order``), for the banded exact gains; ``stop_when_converged``: the
    reference's convergence stop (:data:`CONVERGED_LOGS`)."""

    agent: Agent
    variant: Variant = "paper"
    record_visits: bool = False
    plan_slots: int | None = None
    bandwidth: int | None = None
    stop_when_converged: bool = False


class Fixed(struct.PyTreeNode):
    """What every step of a chunk reads and none writes: the members' MDPs and indicator constants, the schedule, the
    stack's successor rows (episodic grids of several MDPs, else ``None``), and two static facts of the batch."""

    mdps: MDP | BlockMDP
    mdp_index: jax.Array
    consts: IndicatorConstants
    sched: Schedule
    rows: Any
    #: A grid of several plain MDPs steps each member on the stack itself (:func:`jaxmdp.env.step_member`); a
    #: BlockMDP grid, or a single MDP (no gather at all), on the member's own MDP.
    stacked: bool = struct.field(pytree_node=False)
    slots: int = struct.field(pytree_node=False)  # planning slots (Loop.plan_slots or plan_slots_for the batch)


# ---------------------------------------------------------------------------------------------------------------
# Keys
# ---------------------------------------------------------------------------------------------------------------


def keys(key_data: jax.Array, which: int, t: jax.Array) -> jax.Array:
    """Per-member key ``which`` of a member for step ``t`` (vectorised over members)."""
    return fused_random.fold_in(jax.random.wrap_key_data(key_data[:, which]), t)


def init_keys(key_data: jax.Array, tag: str) -> jax.Array:
    """Per-member initialisation key ``tag`` (:data:`INIT_TAGS`)."""
    return keys(key_data, 3, jnp.uint32(INIT_TAGS[tag]))


def plan_keys(key_data: jax.Array, t: jax.Array) -> jax.Array:
    """Per-member planning keys before step ``t``'s action: the initialisation's ``plan`` key before the first
    action (``t = 0``), else planning sub-key ``t + 1``."""
    first = jax.random.key_data(init_keys(key_data, "plan"))
    later = jax.random.key_data(keys(key_data, 2, t + 1))
    return jax.random.wrap_key_data(jnp.where(t == 0, first, later))


# ---------------------------------------------------------------------------------------------------------------
# Initialisation
# ---------------------------------------------------------------------------------------------------------------


def policy_of(agent: Agent) -> Callable:
    """What the indicators evaluate: the agent's ``hints.greedy_actions`` (action indices) where it has them, else
    its ``policy`` (probabilities); the same policy either way."""
    return agent.policy if agent.hints.greedy_actions is None else agent.hints.greedy_actions


def init_carry(
    loop: Loop, mdps: MDP | BlockMDP, mdp_index: jax.Array, hparams: Any, key_data: jax.Array, n_steps: jax.Array,
    orders: jax.Array | None = None,
) -> Carry:
    """Every member reset and its agent initialised: the carry before the first step.

    The agents' first plan runs in the chunk's first planning step (``t = 0``) with the initialisation's ``plan`` key
    (:func:`plan_keys`), so the initialisation program holds no plan and compiles it once less. The members' band
    orders (``orders``, which the indicators use too) go to the agents' specs as a hint for their linear algebra
    (:func:`agents.estimated_model.policy_values`)."""
    agent, hints = loop.agent, loop.agent.hints
    sub = jax.vmap(lambda k: jax.random.key_data(jax.random.split(jax.random.wrap_key_data(k), N_SUBKEYS)))(key_data)

    def one(i, hp, k_reset, k_init, order):
        m = member_mdp(mdps, i)
        obs, env_state = env.reset(k_reset, m)
        spec = spec_of(m, n_steps, None if orders is None else order, None if orders is None else loop.bandwidth)
        return obs, env_state, agent.init(k_init, spec, hp)

    obs, env_state, state = jax.vmap(one)(
        mdp_index, hparams, init_keys(sub, "reset"), init_keys(sub, "init"), mdp_index if orders is None else orders,
    )
    B = mdp_index.shape[0]
    policy = jax.eval_shape(jax.vmap(policy_of(agent)), state)
    dyn = dynamics(mdps)
    stop = loop.stop_when_converged
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
        policy_cache=jnp.zeros((B, 0), policy.dtype) if hints.fixed_policy
        else jnp.full(policy.shape, -1 if jnp.issubdtype(policy.dtype, jnp.integer) else jnp.nan, policy.dtype),
        value_cache=jnp.zeros((B, dyn.n_states), dyn.dtype),
        policy_start=jnp.zeros((B, 0), dyn.dtype) if hints.warm_policy is None
        else jax.vmap(hints.policy_start)(state),
        visits=jnp.zeros((B, dyn.n_states if loop.record_visits else 0), jnp.int32),
        recent_regrets=jnp.full((B, CONVERGED_LOGS if stop else 0), jnp.inf, dyn.dtype),
        stopped_at=jnp.zeros((B, 1 if stop else 0), jnp.int32),
        frozen_state=state if stop else jnp.zeros((B, 0), dyn.dtype),
    )


# ---------------------------------------------------------------------------------------------------------------
# One step: plan, then interact
# ---------------------------------------------------------------------------------------------------------------


#: A batch of at most this many members that the agent lets plan whole (:func:`plans_whole`) gets a slot per member
#: by default, so it always plans whole and its chunk program holds one copy of ``plan``, not two (whole batch and
#: rounds). The price, at most this many plans where fewer members ask, only small runs pay; the second copy cost
#: them about half their compile time (docs/performance.md, Compilation).
SMALL_BATCH = 4


def plan_slots_for(agent: Agent, states: Any) -> int:
    """Planning slots of a lockstep loop (paper App. A.1) over ``states`` (member axis first; arrays, tracers or
    shapes): ``ceil(B / 16)`` for ``B`` members, on a CPU at most ``agent.hints.plan_slot_bytes // m`` (at least
    one), ``m`` one member's state bytes (:func:`~jaxmdp.experiment.planning.default_plan_slots`); ``B`` slots for a
    batch of at most :data:`SMALL_BATCH` members that may plan whole, and for an agent whose members plan together
    (:attr:`~jaxmdp.experiment.agent_interface.RunnerHints.plans_together`)."""
    members, nbytes = batch_bytes(states)
    if agent.hints.plans_together or (members <= SMALL_BATCH and plans_whole(agent, states)):
        return members
    cap = agent.hints.plan_slot_bytes if jax.default_backend() == "cpu" else None
    return default_plan_slots(members, nbytes // max(members, 1), cap)


def plan_step(loop: Loop, fixed: Fixed, c: Carry) -> Carry:
    """The members that ask (all before the first action, the reference's ``before_start_interacting``; never a
    stopped one) plan, under a ``lax.cond`` on "some member asks": the whole batch (result kept where due) when
    ``fixed.slots`` covers it, else in rounds of slots (:func:`jaxmdp.experiment.planning.plan_due`)."""
    agent = loop.agent
    if not agent.plans:
        return c
    B = fixed.mdp_index.shape[0]
    needs = jax.vmap(agent.needs_plan)(c.agent_state) | (c.t == 0)
    if loop.stop_when_converged:
        needs = needs & (c.stopped_at[:, 0] == 0)
    plan_keys_now = lambda: plan_keys(c.key_data, c.t)  # noqa: E731
    if fixed.slots >= B:
        do_plan = lambda state: where_due(needs, jax.vmap(agent.plan)(plan_keys_now(), state), state)  # noqa: E731
    else:
        do_plan = lambda state: plan_due(  # noqa: E731
            agent.plan, fixed.slots, needs, plan_keys_now(), state, plans_whole(agent, state),
            lone_rounds=not agent.episodic,
        )
    return c.replace(agent_state=jax.lax.cond(jnp.any(needs), do_plan, lambda s: s, c.agent_state))


def apart(fn: Callable, *args: Any) -> Any:
    """``fn(*args)``, computed apart from the code that uses its result: on CPU inside a ``lax.cond`` whose
    predicate XLA cannot fold (``optimization_barrier(True)``, unbatched under ``vmap``), elsewhere as it is.

    XLA does not fuse a conditional's computations into their users. The runner computes each step's action this
    way when the agent asks (:attr:`~jaxmdp.experiment.agent_interface.RunnerHints.act_apart`): fused into the step,
    Q-learning's action (its tie-break from the draw's words) went into the fusions that read the tables at the
    action, where it was recomputed for every element they read; apart, it is computed once, with the same results
    (docs/performance.md, Tabular agents). On an accelerator a conditional would cost a synchronisation."""
    if jax.default_backend() != "cpu":
        return fn(*args)
    out = jax.eval_shape(fn, *args)
    always = jax.lax.optimization_barrier(jnp.asarray(True))
    zeros = lambda _: jax.tree.map(lambda o: jnp.zeros(o.shape, o.dtype), out)  # noqa: E731
    return jax.lax.cond(always, lambda a: fn(*a), zeros, args)


def _choose(agent: Agent, key: jax.Array, state: Any, obs: jax.Array, h: jax.Array) -> jax.Array:
    """One member's action (through :func:`apart` when the agent asks)."""
    if agent.hints.act_apart:
        return apart(agent.act, key, state, obs, h)
    return agent.act(key, state, obs, h)


def interact(loop: Loop, fixed: Fixed, c: Carry) -> Carry:
    """Every member acts (a stopped member with its frozen state), the MDP steps, the agent updates."""
    agent, stop = loop.agent, loop.stop_when_converged
    mdps, B = fixed.mdps, fixed.mdp_index.shape[0]
    dtype = dynamics(mdps).dtype
    k_env, k_act = keys(c.key_data, 0, c.t), keys(c.key_data, 1, c.t)

    def one(i, ke, ka, env_state, obs, state, frozen, stopped_at):
        # obs: the state index, or for a BlockMDP the observation sample that step() returned last (so the
        # transition's next_obs is the very sample the agent acts on next, not a second noise draw).
        h = env_state.h
        action = _choose(agent, ka, state, obs, h)
        if stop:  # a stopped member acts with its frozen state
            action = jnp.where(stopped_at[0] > 0, _choose(agent, ka, frozen, obs, h), action)
        if fixed.stacked:  # one gather from the stack per table read (env.step_member)
            obs2, env_state2, reward, terminated, _, info = env.step_member(ke, env_state, action, mdps, i)
        else:
            obs2, env_state2, reward, terminated, _, info = env.step(ke, env_state, action, member_mdp(mdps, i))
        tr = Transition(
            obs=obs, action=action, reward=reward, next_obs=info["final_observation"], h=h, terminated=terminated,
        )
        return obs2, env_state2, agent.update(state, tr), reward, terminated

    obs2, env_state, state, reward, terminated = jax.vmap(one)(
        fixed.mdp_index, k_env, k_act, c.env_state, c.observation, c.agent_state, c.frozen_state, c.stopped_at
    )
    visits = c.visits.at[jnp.arange(B), c.env_state.state].add(1) if loop.record_visits else c.visits
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


def step(loop: Loop, fixed: Fixed, c: Carry) -> Carry:
    """One interaction step of every member: :func:`plan_step`, then :func:`interact`."""
    return interact(loop, fixed, plan_step(loop, fixed, c))


# ---------------------------------------------------------------------------------------------------------------
# A log: the indicators of the members' current policies
# ---------------------------------------------------------------------------------------------------------------


def evaluate_changed(
    dyn: MDP, mdp_index: jax.Array, policy: jax.Array, changed: jax.Array, cache: jax.Array,
    rows: jax.Array | None = None, orders: jax.Array | None = None, bandwidth: int | None = None,
) -> jax.Array:
    """:func:`~jaxmdp.experiment.indicators.policy_values` of the members whose policy ``changed``, ``cache`` for the
    others.

    ``rows``: the stack's :func:`~jaxmdp.dynamic_programming.successor_rows` (episodic grids of several MDPs), from
    which an episodic evaluation of action indices reads each member's rows by (MDP, state, action).

    On a CPU the members are taken one at a time (``lax.map``) and an unchanged member costs nothing: under ``vmap``
    every member would pay for the evaluation (a dense ``O(S^3)`` one when continuous) as soon as one member's policy
    changed, and the policies of a grid change at different times (epochs of UCRL2 and PSRL, Q-learning once its
    greedy policy settles). A continuous member's gain is first certified on the successor lists
    (:func:`~jaxmdp.experiment.indicators.policy_values`, :data:`~jaxmdp.experiment.indicators.ITERATIVE_GAIN_SWEEPS`
    sweeps started cold: a warm start from the previous evaluation certified fewer policies, not more), the dense
    solve running only when that fails. An agent's action indices (``hints.greedy_actions``) are swept on the chosen
    actions' successor slots only. The bounds are not vectorised over the members: their while loops would then run
    as long as the slowest member's (docs/performance.md, Continuous indicators). On an accelerator the members stay in
    lockstep with the dense solve.

    ``orders`` (``[B, S]``) and ``bandwidth`` (static): each member's :func:`jaxmdp.gth.band_order`, for the banded
    elimination of the member-by-member dense solve (unchecked, as every policy's chain fits them).
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
            # The members' own band orders, which every policy's chain fits: no dense branch compiled.
            band = {} if orders is None else dict(order=order, bandwidth=bandwidth, check_band=False)
            return policy_values(member_mdp(dyn, i), p, indicators.ITERATIVE_GAIN_SWEEPS,
                                 give_up=indicators.ITERATIVE_GAIN_GIVE_UP, **band).astype(dtype)

        return jax.lax.cond(ch, evaluate, lambda: old)

    return jax.lax.map(one, (mdp_index, policy, changed, cache, mdp_index if orders is None else orders))


class Logged(struct.PyTreeNode):
    """The fields of the carry that a log writes (only they leave the log's ``lax.cond``: with the whole carry as
    its result, XLA copied the agent tables at every log)."""

    policy_cache: jax.Array
    value_cache: jax.Array
    logged: Sums
    last_log: jax.Array
    policy_start: jax.Array
    recent_regrets: jax.Array
    stopped_at: jax.Array
    frozen_state: Any

    @classmethod
    def of(cls, c: Carry) -> "Logged":
        """The fields as the carry holds them (what a step that is not a log keeps)."""
        return cls(c.policy_cache, c.value_cache, c.logged, c.last_log, c.policy_start, c.recent_regrets,
                   c.stopped_at, c.frozen_state)


def evaluated_states(loop: Loop, c: Carry) -> Any:
    """The agent states a log evaluates: a stopped member's frozen state, the others' live ones."""
    if not loop.stop_when_converged:
        return c.agent_state
    return where_due(c.stopped_at[:, 0] == 0, c.agent_state, c.frozen_state)


def changed_policy(agent: Agent, c: Carry) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The policy to cache, which members' policies changed since the previous log, and the next log's warm start
    (``hints.warm_policy``: the policy computed from the previous log's)."""
    hints = agent.hints
    B = c.value_cache.shape[0]
    if hints.fixed_policy:  # evaluated at the first log (the previous log at step 0), never again
        return c.policy_cache, jnp.broadcast_to(c.last_log == 0, (B,)), c.policy_start
    if hints.warm_policy is None:
        policy, start = jax.vmap(policy_of(agent))(c.agent_state), c.policy_start
    else:
        policy, start = jax.vmap(hints.warm_policy)(c.agent_state, c.policy_start)
    # max over uint8, not any over bool: XLA's CPU reduction of a predicate is several times slower. Reduced over the
    # trailing axes as they are: flattened first (reshape(B, -1)), the comparison fused with the greedy extraction
    # ran an order of magnitude slower (docs/performance.md, Tabular agents).
    changed = jnp.max((policy != c.policy_cache).astype(jnp.uint8), axis=tuple(range(1, policy.ndim))) > 0
    return policy, changed, start


def converged(
    loop: Loop, fixed: Fixed, c: Carry, live: Any, normalized_regret: jax.Array
) -> tuple[jax.Array, jax.Array, Any]:
    """The convergence stop at a log (:data:`CONVERGED_LOGS`): the recent regrets with this log's, when each member
    stopped (``c.t`` for one that stops now) and the frozen states (``live`` for one that stops now)."""
    if not loop.stop_when_converged:
        return c.recent_regrets, c.stopped_at, c.frozen_state
    dyn = dynamics(fixed.mdps)
    r = normalized_regret.astype(dyn.dtype)
    recent = jnp.concatenate([c.recent_regrets[:, 1:], r[:, None]], axis=1)
    is_converged = (
        (c.t * CONVERGED_AFTER_DIVISOR > fixed.sched.n_steps)
        & jnp.all(jnp.abs(recent) <= CONVERGED_TOLERANCE[dyn.episodic], axis=1)
        & (jnp.abs(r) <= CONVERGED_CURRENT_TOLERANCE)
    )
    stopping = (c.stopped_at[:, 0] == 0) & is_converged
    stopped_at = jnp.where(stopping[:, None], c.t, c.stopped_at)
    return recent, stopped_at, where_due(stopping, live, c.frozen_state)


def log(loop: Loop, fixed: Fixed, c: Carry) -> Logged:
    """A log after ``c.t`` steps: the indicators of every member's current policy, charged for the ``c.t -
    c.last_log`` steps since the previous log.

    Policy evaluation is the expensive half of an indicator: a member whose policy is unchanged since the previous
    log reuses its values (exactly: they cover every state), and the evaluation is skipped altogether when no
    member's policy changed."""
    agent = loop.agent
    dyn = dynamics(fixed.mdps)  # the indicators evaluate policies on the states' dynamics
    dtype = dyn.dtype
    live = c.agent_state
    c = c.replace(agent_state=evaluated_states(loop, c))
    policy, changed, start = changed_policy(agent, c)

    def evaluate(cache: jax.Array) -> jax.Array:
        current = jax.vmap(policy_of(agent))(c.agent_state) if agent.hints.fixed_policy else policy
        return evaluate_changed(dyn, fixed.mdp_index, current, changed, cache, fixed.rows, fixed.consts.state_order,
                                loop.bandwidth)

    values = jax.lax.cond(jnp.any(changed), evaluate, lambda cache: cache, c.value_cache)
    inst = jax.vmap(lambda i, k, v, s, s0: instant_from_values(member_mdp(dyn, i), k, v, s, s0, loop.variant))(
        fixed.mdp_index, fixed.consts, values, c.env_state.state, c.last_start
    )
    k = (c.t - c.last_log).astype(dtype)
    x = jnp.stack([inst.regret, inst.expected_reward, inst.normalized_regret], axis=-1) * k
    recent, stopped_at, frozen = converged(loop, fixed, c, live, inst.normalized_regret)
    return Logged(policy, values, c.logged.add(x.astype(dtype)), c.t, start, recent, stopped_at, frozen)


# ---------------------------------------------------------------------------------------------------------------
# Records, segments and a chunk
# ---------------------------------------------------------------------------------------------------------------


def diagnostic_names(agent: Agent, agent_states: Any) -> tuple[str, ...]:
    """The names of ``agent.diagnostics`` (sorted; none without it) for batched ``agent_states`` (or their shapes)."""
    if agent.diagnostics is None:
        return ()
    return tuple(sorted(jax.eval_shape(jax.vmap(agent.diagnostics), agent_states)))


def diagnostic_values(agent: Agent, agent_states: Any) -> list[jax.Array]:
    """``[B]`` arrays of the diagnostics of batched ``agent_states``, in :func:`diagnostic_names` order."""
    if agent.diagnostics is None:
        return []
    d = jax.vmap(agent.diagnostics)(agent_states)
    return [d[name] for name in sorted(d)]


def record(
    agent: Agent, c: Carry, steps: jax.Array, values: jax.Array, j: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Record ``j`` of a chunk: the step count and every member's row (:data:`AGENT_COLUMNS`, then the agent's
    diagnostics)."""
    dtype = values.dtype
    # The order of AGENT_COLUMNS: regret, reward, expected reward, normalised regret.
    logged = c.logged.value
    row = [logged[:, 0], c.reward.value, logged[:, 1], logged[:, 2]]
    row = jnp.stack(row + [x.astype(dtype) for x in diagnostic_values(agent, c.agent_state)], axis=-1)
    return steps.at[j].set(c.t), values.at[j].set(row), j + 1


def segment(loop: Loop, fixed: Fixed, t_end: jax.Array, state: tuple) -> tuple:
    """The steps up to the next log point (or ``t_end``, the chunk's end) in a loop of their own, then the log and
    the record if due: a per-step ``lax.cond`` over the whole carry made XLA copy the ``[B, H, S, A]`` policy cache
    at every step. ``state``: ``(carry, steps, values, records written)``."""
    c, steps, values, j = state
    sched = fixed.sched
    next_log = jnp.minimum((c.t // sched.log_period + 1) * sched.log_period, sched.n_steps)
    c = jax.lax.fori_loop(0, jnp.minimum(next_log, t_end) - c.t, lambda _, c: step(loop, fixed, c), c)
    is_log = (c.t % sched.log_period == 0) | (c.t == sched.n_steps)
    out = jax.lax.cond(is_log, lambda c: log(loop, fixed, c), Logged.of, c)
    c = c.replace(policy_cache=out.policy_cache, value_cache=out.value_cache, logged=out.logged,
                  last_log=out.last_log, policy_start=out.policy_start, recent_regrets=out.recent_regrets,
                  stopped_at=out.stopped_at, frozen_state=out.frozen_state)
    is_record = (c.t % sched.record_period == 0) | (c.t == sched.n_steps)
    steps, values, j = jax.lax.cond(is_record, lambda a: record(loop.agent, c, *a), lambda a: a, (steps, values, j))
    return c, steps, values, j


def chunk(
    loop: Loop, capacity: int, carry: Carry, mdps: MDP | BlockMDP, mdp_index: jax.Array, consts: IndicatorConstants,
    sched: Schedule, n: jax.Array,
) -> tuple[Carry, jax.Array, jax.Array, jax.Array]:
    """``n`` more steps (traced) of every member: ``(carry, steps[capacity], values[capacity, B, columns],
    records written)``, at most ``capacity`` records."""
    B = mdp_index.shape[0]
    dyn = dynamics(mdps)
    fixed = Fixed(
        mdps=mdps, mdp_index=mdp_index, consts=consts, sched=sched,
        # Episodic evaluations on several MDPs read the stack's packed successor rows, built once per chunk.
        rows=dp.successor_rows(dyn) if dyn.episodic and n_distinct(dyn) > 1 else None,
        stacked=isinstance(mdps, MDP) and n_distinct(mdps) > 1,
        slots=plan_slots_for(loop.agent, carry.agent_state) if loop.plan_slots is None else loop.plan_slots,
    )
    t_end = carry.t + n
    n_columns = len(AGENT_COLUMNS) + len(diagnostic_names(loop.agent, carry.agent_state))
    init = (carry, jnp.zeros((capacity,), jnp.int32), jnp.zeros((capacity, B, n_columns), dyn.dtype),
            jnp.zeros((), jnp.int32))
    return jax.lax.while_loop(lambda s: s[0].t < t_end, lambda s: segment(loop, fixed, t_end, s), init)
