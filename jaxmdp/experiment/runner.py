"""The lockstep experiment runner: many (MDP, hyperparameters, seed) members in one compiled program.

A run drives a flat batch of ``B`` *members* (a :class:`Grid`), each with its own MDP, hyperparameters and key,
through ``n_steps`` agent/MDP interaction steps (paper §3.3 and App. A.1; docs/measures.md §6.1):

* the time loop is a ``lax.fori_loop`` over the steps between two log points, whose body ``vmap``s ``jaxmdp.step``
  and the agent's ``act``/``update`` over the batch, inside a ``lax.while_loop`` over log points (with the log's
  ``lax.cond`` inside the per-step body, XLA copied the whole carry, policy cache included, at every step); the step,
  the plan, the log and the record are the pure functions of :mod:`jaxmdp.experiment.lockstep`, compiled by
  :mod:`jaxmdp.experiment.programs`;
* planning (``agent.plan``) runs under a ``lax.cond`` whose predicate is unbatched, "some member needs to plan", and
  only the members that asked are planned, ``plan_slots`` at a time (:mod:`jaxmdp.experiment.planning`), so planning
  is paid at boundaries only and for those members only; every member plans before its first action, in the same
  step (the initialisation program holds no plan, so the plan is compiled once less);
* indicator logging (:mod:`jaxmdp.experiment.indicators`, exact policy evaluation of ``agent.policy``, or of
  ``agent.hints.warm_policy`` started from what the member's previous log returned) runs under a ``lax.cond`` on "this
  is a log step" (a chunk may end between two): after every ``log_period`` steps and after the last step. A log made
  after ``c`` steps covers the ``k = c - c_prev`` steps since the previous log (the paper's approximation;
  ``log_period=1`` is the exact mode): ``cumulative_regret += k r_c`` and likewise for the normalised regret and the
  expected reward. The cumulative (sampled) reward is summed every step. All sums are compensated (Kahan) so that
  float32 keeps its precision over long runs;
* memory is flat in ``n_steps``: the carry holds running sums only, and a run emits a fixed number of records
  (``n_records`` evenly spaced snapshots, the last one after step ``n_steps``);
* ``record_visits=True`` adds an ``[B, S]`` count of the states each member acted in (``RunResult.visits``); it is a
  static setting, so a run without it compiles no counting at all.

This module is the host driver: it validates a run's settings, compiles its programs, runs them in chunks
(:func:`run`), shows progress (:mod:`jaxmdp.experiment.progress`), appends each chunk's records to a CSV and can
checkpoint the carry so that an interrupted run resumes without losing finished work. Every random draw comes from the
member's key folded with the step index, so a run's results do not depend on how it was chunked or whether it was
resumed. Learning runs for ``n_steps`` steps and compute time is reported beside the results (the reference instead
stops learning after a wall-clock budget, docs/benchmark.md §2). ``stop_when_converged=True`` adds the reference's
other stop (docs/measures.md §6.4): a member whose normalised regret has been near 0 at ten logs in a row past a fifth
of the run stops learning and acts with its agent as it is for the rest of the run.

Step bookkeeping (differs from the reference's off-by-one, docs/measures.md §6.1, which logs at loop index ``t`` with
``t + 1`` steps done but labels and charges ``t``): the record labelled ``steps = c`` is made after exactly ``c``
interaction steps and agent updates, every cumulative quantity covers exactly those ``c`` steps, and the indicator
of a log evaluates the policy estimate after the ``c``-th update.
"""

from __future__ import annotations

import dataclasses
import os
import time
import warnings
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp import env
from jaxmdp._checks import Variant, check_bool, check_int, check_variant
from jaxmdp.blockmdp.block_mdp import BlockMDP
from jaxmdp.experiment.agent_interface import Agent, spec_of, where_due
from jaxmdp.experiment.checkpoints import fingerprint, load_checkpoint, save_checkpoint
from jaxmdp.experiment.indicators import AGENT_COLUMNS, IndicatorConstants
from jaxmdp.experiment.lockstep import (  # noqa: F401 (the convergence stop's constants and the carry, re-exported)
    CONVERGED_AFTER_DIVISOR,
    CONVERGED_CURRENT_TOLERANCE,
    CONVERGED_LOGS,
    CONVERGED_TOLERANCE,
    Carry,
    Schedule,
    Sums,
    diagnostic_names,
    diagnostic_values,
    plan_slots_for,
)
from jaxmdp.experiment.memory import ProgramTooLarge, check_fits
from jaxmdp.experiment.members import Grid, dynamics, grid, member_mdp, product, seed_keys, stack_hparams, take_members
from jaxmdp.experiment.programs import (
    chunk_program,
    compile_lowered,
    compile_options,
    constants_program,
    init_program,
    signature,
)
from jaxmdp.experiment.progress import Progress
from jaxmdp.experiment.records import MEMBER_COLUMNS, RunResult, append_rows, csv_rows, record_steps, truncate_csv
from jaxmdp.gth import band_order
from jaxmdp.mdp import MDP

# The lockstep loop's functions and the program builders under the private names by which tests reach them here;
# jaxmdp.experiment.lockstep and jaxmdp.experiment.programs define them (patch them there).
from jaxmdp.experiment.lockstep import apart as _apart  # noqa: F401
from jaxmdp.experiment.lockstep import evaluate_changed as _evaluate_changed  # noqa: F401
from jaxmdp.experiment.lockstep import policy_of as _policy_of  # noqa: F401
from jaxmdp.experiment.programs import chunk_program as _chunk_program  # noqa: F401
from jaxmdp.experiment.programs import constants_program as _constants_program  # noqa: F401
from jaxmdp.experiment.programs import init_program as _init_program  # noqa: F401

__all__ = [
    "Grid", "grid", "product", "seed_keys", "stack_hparams", "take_members", "RunResult", "run", "record_steps",
    "MEMBER_COLUMNS", "ProgramTooLarge", "DEFAULT_CHUNKS", "default_chunk_steps", "plan_slots_for",
]


# ---------------------------------------------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------------------------------------------


def _n_shards(n_members: int, shards: int | None) -> int:
    """The devices a run's members are sharded over: ``shards``, which must divide them, or by default the count
    that puts the fewest members on a device, then pads the fewest (:func:`_padding`): 5 members on two devices
    run as 3 + 3, not 5 on one (docs/performance.md, Benchmark wall time)."""
    available = jax.local_device_count()
    if shards is None:
        per_device = lambda d: -(-n_members // d)  # noqa: E731
        return min(range(1, min(available, n_members) + 1), key=lambda d: (per_device(d), d * per_device(d)))
    shards = check_int("shards", shards)
    if shards > available or n_members % shards:
        raise ValueError(f"shards must divide the {n_members} members and be at most the {available} local devices; "
                         f"got {shards}")
    return shards


def _padding(n_members: int, n_padded: int) -> np.ndarray:
    """The members a run of ``n_members`` runs on ``n_padded`` slots (:func:`_n_shards`): each, then copies of the
    last. A copy computes what its original does (members never interact), so its results are dropped and the
    checkpoint holds the real members only: it resumes on any device count."""
    return np.minimum(np.arange(n_padded), n_members - 1)


def _validate(agent: Agent, g: Grid, variant: str) -> None:
    if not isinstance(agent, Agent):
        raise ValueError(f"agent must be a jaxmdp.experiment.agent_interface.Agent; got {type(agent).__name__}")
    for field in ("whole_batch_plans", "whole_batch_bytes", "plan_slot_bytes"):
        if getattr(agent.hints, field) is not None:
            check_int(f"RunnerHints.{field}", getattr(agent.hints, field), 0,
                      context=f" or None (agent {agent.name!r})")
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
        hints = agent.hints
        greedy = hints.greedy_actions(state) if hints.greedy_actions is not None else None
        warm = None
        if hints.warm_policy is not None:
            start = hints.policy_start(state)
            warm = (start, *hints.warm_policy(state, start))
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


# ---------------------------------------------------------------------------------------------------------------
# Results and progress
# ---------------------------------------------------------------------------------------------------------------


def _warn_diagnostics(agent: Agent, agent_states: Any) -> None:
    """A warning per non-zero diagnostic at the end of a run: the agent, the total and how many members."""
    for name, x in zip(diagnostic_names(agent, agent_states), diagnostic_values(agent, agent_states)):
        x = np.asarray(x)
        if np.any(x != 0):
            warnings.warn(
                f"{agent.name}: {name} = {int(x.sum())} over the run ({int(np.sum(x != 0))} of {x.size} members); "
                f"see the '{name}' column of the records",
                RuntimeWarning,
                stacklevel=3,
            )


def _final_states(carry: Carry, stop_when_converged: bool) -> Any:
    """The members' agent states at the end of a run (numpy): for a member that stopped learning, its frozen state."""
    states = carry.agent_state
    if stop_when_converged:
        states = where_due(carry.stopped_at[:, 0] == 0, states, carry.frozen_state)
    return jax.tree.map(np.asarray, states)


def _display(progress: bool | Progress, agent: Agent, grid: Grid, n_steps: int) -> tuple[Progress, bool]:
    """The run's progress display and whether the run owns it (makes and closes it): the caller's
    :class:`~jaxmdp.experiment.progress.Progress`, or one counting this run's member-steps on stderr."""
    if isinstance(progress, Progress):
        return progress, False
    if not isinstance(progress, (bool, np.bool_)):
        raise ValueError(f"progress must be True, False or a jaxmdp.experiment.progress.Progress; got {progress!r}")
    desc = f"{agent.name}, {grid.n_members} member{'s' if grid.n_members > 1 else ''}"
    return Progress(grid.n_members * n_steps, desc, quiet=not progress), True


# ---------------------------------------------------------------------------------------------------------------
# A run's settings, programs and progress
# ---------------------------------------------------------------------------------------------------------------


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
class _RunState:
    """Where a run stands: the loop's carry, the records so far and the run seconds of earlier calls (a resumed
    run)."""

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


# ---------------------------------------------------------------------------------------------------------------
# Compilation
# ---------------------------------------------------------------------------------------------------------------


#: Fewest states for which the runner eliminates on a band (:func:`_band`). Below it the dense elimination costs about
#: the same, and a banded fallback costs compile time per runner (docs/performance.md, Continuous indicators).
BAND_MIN_STATES = 64


def _band(mdps: MDP | BlockMDP, mdp_index: np.ndarray) -> tuple[jax.Array | None, int | None]:
    """Each member's band order (``[B, S]``) and their bandwidth (:func:`jaxmdp.gth.band_order`, host side) when the
    exact continuous gains are taken member by member (a CPU), the MDPs have at least :data:`BAND_MIN_STATES` states
    and the band is under half of them; else ``(None, None)``: under ``vmap`` (an accelerator) the banded and dense
    eliminations would both run."""
    dyn = dynamics(mdps)
    if dyn.episodic or jax.default_backend() != "cpu" or dyn.n_states < BAND_MIN_STATES:
        return None, None
    order, width = band_order(dyn)
    if 2 * width >= dyn.n_states:
        return None, None
    order = order.reshape(-1, dyn.n_states)
    return jax.device_put(order[np.asarray(mdp_index) if len(order) > 1 else np.zeros(len(mdp_index), int)]), width


def _compile(agent: Agent, grid: Grid, settings: _Settings, display: Progress) -> _Program:
    """Compute the indicator constants and compile the initialisation and chunk programs (timed together, each
    announced on ``display``); raise :class:`~jaxmdp.experiment.memory.ProgramTooLarge` before anything runs if one of
    them would not fit in memory."""
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
    with display.compiling("the indicator constants"):  # dispatched: they are computed while the rest compiles
        consts = constants_program(settings.variant, signature(mdps, mdp_index))(mdps, mdp_index)
        orders, bandwidth = _band(mdps, grid.mdp_index)
        consts = consts.replace(state_order=orders)
    options = compile_options(jax.default_backend())
    init_args = (mdps, mdp_index, hparams, key_data, sched.n_steps, orders)
    init_jit = init_program(agent, settings.record_visits, bandwidth, settings.stop_when_converged,
                            signature(*init_args))
    with display.compiling("the initialisation program"):
        init_fn = compile_lowered(init_jit.lower(*init_args), options)
    carry_shape = jax.eval_shape(init_jit, *init_args)
    leaves, treedef = jax.tree.flatten(carry_shape)
    carry_layout = (treedef, tuple(x.ndim for x in leaves))
    chunk_args = (carry_shape, mdps, mdp_index, consts, sched, jnp.int32(0))
    chunk_fn = chunk_program(
        agent, settings.variant, settings.capacity, settings.n_shards, carry_layout, settings.record_visits,
        settings.plan_slots, bandwidth, settings.stop_when_converged, signature(*chunk_args),
    )
    with display.compiling("the chunk program"):
        chunk_exe = compile_lowered(chunk_fn.lower(*chunk_args), options)
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


# ---------------------------------------------------------------------------------------------------------------
# Start or resume, the chunk loop, and run
# ---------------------------------------------------------------------------------------------------------------


def _start_or_resume(
    program: _Program, n_members: int, run_id: str, ckpt: Path | None, csv_file: Path | None, resume: bool
) -> _RunState:
    """Continue this run's checkpoint if there is one (and ``resume``), dropping CSV rows written after it;
    otherwise initialise every member and start a fresh CSV."""
    if ckpt is not None and resume and ckpt.exists():
        like = jax.tree.map(lambda x: x if x.ndim == 0 else jax.ShapeDtypeStruct((n_members, *x.shape[1:]), x.dtype),
                            program.carry_shape)
        carry, steps_done, values_done, meta = load_checkpoint(ckpt, like, run_id)
        carry = jax.tree.map(jnp.asarray, take_members(carry, _padding(n_members, len(program.mdp_index))))
        if csv_file is not None:
            truncate_csv(csv_file, int(carry.t), program.diagnostic_names)
        return _RunState(carry, steps_done, values_done, float(meta["run_s"]))
    carry = program.init(program.mdps, program.mdp_index, program.hparams, program.key_data, program.sched.n_steps,
                         program.consts.state_order)
    jax.block_until_ready(carry)
    if csv_file is not None:
        csv_file.parent.mkdir(parents=True, exist_ok=True)
        truncate_csv(csv_file, -1, program.diagnostic_names)
    steps_done = np.zeros((0,), np.int64)
    n_columns = len(AGENT_COLUMNS) + len(program.diagnostic_names)
    values_done = np.zeros((0, n_members, n_columns), np.dtype(dynamics(program.mdps).dtype))
    return _RunState(carry, steps_done, values_done, 0.0)


def _run_chunks(
    agent: Agent,
    grid: Grid,
    program: _Program,
    start: _RunState,
    settings: _Settings,
    run_id: str,
    ckpt: Path | None,
    csv_file: Path | None,
    display: Progress,
    stop_after_chunks: int | None,
) -> tuple[_RunState, float]:
    """Run the chunk program until ``n_steps`` (or ``stop_after_chunks``), appending each chunk's records to the CSV,
    checkpointing and advancing ``display`` by the chunk's member-steps after each; returns where the run stands and
    its run seconds over every call that ran it."""
    n_steps, n_members = settings.n_steps, grid.n_members  # the program's members may be padded (_padding)
    carry, steps_done, values_done = start.carry, start.steps, start.values
    consts_np = take_members(program.consts, slice(n_members))
    t_start = time.perf_counter()
    chunks = 0
    t = int(carry.t)
    while t < n_steps:
        n = min(settings.chunk_steps, n_steps - t)
        carry, steps, values, j = program.chunk(
            carry, program.mdps, program.mdp_index, program.consts, program.sched, jnp.int32(n)
        )
        j = int(j)
        steps, values = np.asarray(steps)[:j], np.asarray(values)[:j, :n_members]
        elapsed = start.elapsed_before + time.perf_counter() - t_start
        steps_done = np.concatenate([steps_done, steps])
        values_done = np.concatenate([values_done, values])
        if csv_file is not None and j:
            per_second = np.full((j,), int(carry.t) / elapsed)
            append_rows(csv_file, csv_rows(grid, steps, values, consts_np, per_second))
        if ckpt is not None:
            meta = {"fingerprint": run_id, "run_s": elapsed, "t": int(carry.t), "agent": agent.name}
            save_checkpoint(ckpt, take_members(carry, slice(n_members)), steps_done, values_done, meta)
        display.update(grid.n_members * (int(carry.t) - t))
        t = int(carry.t)
        chunks += 1
        if stop_after_chunks is not None and chunks >= stop_after_chunks and t < n_steps:
            break
    run_s = start.elapsed_before + time.perf_counter() - t_start
    return _RunState(carry, steps_done, values_done, start.elapsed_before), run_s


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
    progress: bool | Progress = False,
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
      progress: ``True``: show a progress bar on stderr when it is a terminal (nothing otherwise;
        :mod:`jaxmdp.experiment.progress`): member-steps done, member-steps per second, time left, and each program
        compiled with the seconds it took. A :class:`~jaxmdp.experiment.progress.Progress` instead: advance that
        display by this run's member-steps after each chunk (a bar counting several runs, as the benchmark's); a
        resumed run takes its finished steps off that display's total. The results do not depend on it.
      stop_after_chunks: stop after this many chunks of this call (to test interruption; the result then holds the
        records so far).
      shards: split the members over this many local devices, which must divide them (default: the count of at
        most ``jax.local_device_count()`` that puts the fewest members on a device, the members padded to a multiple
        of it with copies of the last one, whose results are dropped). XLA runs one lockstep loop on one core; to
        use every core of a CPU, start Python with ``XLA_FLAGS=--xla_force_host_platform_device_count=<cores>``
        (before JAX is imported).
      record_visits: also count, per member, the states it took its actions in (``RunResult.visits``, ``[B, S]``
        int, summing to ``n_steps`` per member; for a BlockMDP the latent states). Off by default: the loop then
        carries and computes nothing for it.
      plan_slots: members planned at once when some members of a lockstep loop (a shard) need a plan
        (:mod:`jaxmdp.experiment.planning`): rounds of this many until all are served, so planning costs in
        proportion to the members that asked; default ``ceil(members / 16)`` per shard, on a CPU at most
        ``agent.hints.plan_slot_bytes`` of agent state a round, and a slot per member for a shard of at most
        :data:`~jaxmdp.experiment.lockstep.SMALL_BATCH` members that may plan whole (:func:`plan_slots_for`). A value
        at least a shard's members plans the whole shard whenever one member asks. The results do not depend on it.
      memory_limit: bytes the compiled programs may need (all shards together on a CPU, per device on an
        accelerator); default what the devices have available (:mod:`jaxmdp.experiment.memory`).
      stop_when_converged: the reference's convergence stop (docs/measures.md §6.4, [quirk]): a member stops learning
        (it acts with, and is evaluated on, its agent state as it is; ``RunResult.agent_state`` holds that state) at
        the first log past ``1 /`` :data:`CONVERGED_AFTER_DIVISOR` of the steps where its last :data:`CONVERGED_LOGS`
        normalised regrets are within :data:`CONVERGED_TOLERANCE` of 0 and the current one within
        :data:`CONVERGED_CURRENT_TOLERANCE`. Its later logs evaluate that agent state's policy as before (the
        reference computes its regret once and reuses it). ``RunResult.stopped_at`` tells when. The loop then holds
        each member's agent state twice (live and frozen) and computes each action twice. Off by default: the paper's
        protocol learns to the end.

    Raises:
      ValueError: before anything compiles, for an episodic agent on continuous MDPs (or the reverse), an agent whose
        policy or action does not fit the MDPs' ``S``/``A``/``H``, non-positive ``n_steps``, ``log_period`` or
        ``n_records``, a ``progress`` that is neither a bool nor a ``Progress``, hyperparameters outside their domain
        (``agent.check_hparams``), an ``agent.hints.whole_batch_plans`` or ``agent.hints.whole_batch_bytes`` that is
        neither ``None`` nor an integer >= 0, or a checkpoint of another run.
      ProgramTooLarge: after compiling, before anything runs, when a program needs more memory than
        ``memory_limit`` (a ``MemoryError``; split the members over several calls).
    """
    settings = _validated_settings(
        agent, grid, n_steps, log_period, n_records, variant, chunk_steps, shards, record_visits, plan_slots,
        memory_limit, stop_when_converged,
    )
    display, own_display = _display(progress, agent, grid, settings.n_steps)
    n_members = grid.n_members
    try:
        n_padded = -(-n_members // settings.n_shards) * settings.n_shards
        program = _compile(agent, grid if n_padded == n_members else grid.take(_padding(n_members, n_padded)),
                           settings, display)
        run_id = fingerprint(agent.name, grid, settings.n_steps, settings.log_period, settings.record_period, variant)
        if record_visits:  # a checkpoint of a run without counts cannot continue one with them (and vice versa)
            run_id += "+visits"
        if stop_when_converged:
            run_id += "+converged-stop"
        ckpt = Path(checkpoint_path) if checkpoint_path is not None else None
        csv_file = Path(csv_path) if csv_path is not None else None
        start = _start_or_resume(program, grid.n_members, run_id, ckpt, csv_file, resume)
        if int(start.carry.t):
            display.write(f"resuming {agent.name} at step {int(start.carry.t)} of {settings.n_steps} ({ckpt})")
            display.skip(grid.n_members * int(start.carry.t))
        done, run_s = _run_chunks(
            agent, grid, program, start, settings, run_id, ckpt, csv_file, display, stop_after_chunks
        )
    finally:
        if own_display:
            display.close()
    _warn_diagnostics(agent, take_members(done.carry.agent_state, slice(n_members)))  # not the copies
    return RunResult(
        steps=done.steps,
        values=done.values,
        constants=take_members(program.consts, slice(n_members)),
        grid=grid,
        agent=agent.name,
        compile_s=program.compile_s,
        run_s=run_s,
        n_steps=settings.n_steps,
        log_period=settings.log_period,
        record_period=settings.record_period,
        variant=variant,
        agent_state=take_members(_final_states(done.carry, stop_when_converged), slice(n_members)),
        visits=np.asarray(done.carry.visits)[:n_members] if record_visits else None,
        stopped_at=np.asarray(done.carry.stopped_at[:n_members, 0]) if stop_when_converged else None,
        diagnostic_names=program.diagnostic_names,
    )
