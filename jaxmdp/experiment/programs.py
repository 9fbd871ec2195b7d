"""The runner's compiled programs: initialisation, a chunk of the lockstep loop, and the indicator constants.

Each builder returns a ``jax.jit``-ed function of :mod:`jaxmdp.experiment.lockstep`'s pure functions, with the run's
static settings bound. The builders are cached with a bound (least recently used first out), keyed by the agent (by
identity: ``Agent`` compares and hashes as an object), the static settings and the inputs' :func:`signature`. A cached
entry holds its agent, so an agent's identity cannot be reused while its programs are cached.

Why the signature is part of the key: ``jax.jit`` keeps every executable it compiled for as long as the jitted function
lives, and on a CPU each executable holds thousands of the process's memory mappings (about 1 500 for the smallest
runner's three programs, 4 000 for PSRL continuous at 820 states), which Linux bounds (``vm.max_map_count``, 65 530 by
default); past the bound LLVM cannot map a new program's code and the process aborts. Keyed by settings alone, one
jitted function per agent collected a program for every shape a long benchmark run met. Keyed by signature too, the
bound counts executables, and an evicted entry's executables are freed with it (docs/performance.md, Compilation).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import jax
import numpy as np

from jaxmdp._checks import Variant
from jaxmdp.experiment import lockstep
from jaxmdp.experiment.agent_interface import Agent
from jaxmdp.experiment.indicators import indicator_constants
from jaxmdp.experiment.members import dynamics

__all__ = ["init_program", "chunk_program", "constants_program", "compile_options", "compile_lowered", "signature",
           "MAX_CACHED_PROGRAMS", "CPU_COMPILER_OPTIONS"]

#: Programs of each kind kept compiled (see the module docstring): enough for a tuning search or a test module that
#: comes back to a few shapes, few enough that three kinds of the largest programs stay far under the mappings bound.
MAX_CACHED_PROGRAMS = 8


def signature(*args: Any) -> tuple:
    """A hashable key of ``args``' tree structure and their leaves' shapes and dtypes: the builders' ``signature``
    argument, so that one cached entry compiles one shape (module docstring). It only chooses the cache entry;
    ``jax.jit`` still checks the inputs of every call."""
    leaves, treedef = jax.tree.flatten(args)
    return treedef, tuple((tuple(getattr(x, "shape", ())), str(getattr(x, "dtype", type(x).__name__))) for x in leaves)

#: XLA options for the runner's programs on a CPU, given per compilation (not through ``XLA_FLAGS``, which would
#: change the process). Region-based copy insertion lets the lockstep loop update an agent's parameters in place
#: where the planning conditional returns them: without it XLA copied every parameter and optimiser array out of the
#: conditional and again into the loop's carry at every step (ActorCriticRNN 64 seeds: 8.7 k -> 17.5 k agent-steps/s,
#: the actor-critic 168 k -> 543 k; results bit-identical; docs/performance.md, Deep agents).
CPU_COMPILER_OPTIONS = {"xla_cpu_copy_insertion_use_region_analysis": True}


def compile_options(platform: str) -> dict[str, Any] | None:
    """The compiler options of the runner's programs on ``platform`` (``jax.default_backend()`` names):
    :data:`CPU_COMPILER_OPTIONS` on ``"cpu"``, none elsewhere."""
    return dict(CPU_COMPILER_OPTIONS) if platform == "cpu" else None


def compile_lowered(lowered: jax.stages.Lowered, options: dict[str, Any] | None) -> jax.stages.Compiled:
    """``lowered.compile(options)``; a jaxlib that does not know one of the options (they only change speed) compiles
    without them instead of failing."""
    try:
        return lowered.compile(options)
    except Exception as error:  # matched by its message: jaxlib's runtime error type is no stable public name
        if options and "No such compile option" in str(error):
            return lowered.compile()
        raise


@functools.lru_cache(maxsize=MAX_CACHED_PROGRAMS)
def init_program(
    agent: Agent, record_visits: bool = False, bandwidth: int | None = None, stop_when_converged: bool = False,
    signature: tuple | None = None,
) -> Callable:
    """``init(mdps, mdp_index, hparams, key_data, n_steps, orders=None) -> Carry``
    (:func:`~jaxmdp.experiment.lockstep.init_carry`), jitted; ``signature`` (:func:`signature` of its inputs) only
    keys the cache."""
    loop = lockstep.Loop(agent, record_visits=record_visits, bandwidth=bandwidth,
                         stop_when_converged=stop_when_converged)
    return jax.jit(functools.partial(lockstep.init_carry, loop))


@functools.lru_cache(maxsize=MAX_CACHED_PROGRAMS)
def chunk_program(
    agent: Agent,
    variant: Variant,
    capacity: int,
    n_shards: int,
    carry_treedef: Any,
    record_visits: bool = False,
    plan_slots: int | None = None,
    bandwidth: int | None = None,
    stop_when_converged: bool = False,
    signature: tuple | None = None,
) -> Callable:
    """``chunk(carry, mdps, mdp_index, consts, schedule, n) -> (carry, steps[capacity], values[capacity, B, 4],
    n_written)`` (:func:`~jaxmdp.experiment.lockstep.chunk`): ``n`` more steps (traced), recording at most
    ``capacity`` snapshots; the carry is donated.

    ``stop_when_converged`` (static): the reference's convergence stop (:data:`~jaxmdp.experiment.lockstep.
    CONVERGED_LOGS`). A member that has stopped acts with, and is evaluated on, a copy of its agent state made when it
    stopped; its live state plans no more and is not seen again. (Keeping the live state instead, merged with its
    update at every step, would read and write the whole state per step.)

    ``bandwidth``: the members' band orders' (``consts.state_order``), for the banded exact gains.

    With ``n_shards > 1`` the members are split over that many local devices with ``shard_map``; each shard runs its
    own loop (its own "some member needs to plan" predicate), so shards never communicate. A grid whose stacked MDPs
    have no Beta reward anywhere (static ``MDP.stochastic_rewards``) compiles no reward draw. ``plan_slots``: members
    planned at once (:func:`jaxmdp.experiment.planning.plan_due`; default
    :func:`~jaxmdp.experiment.lockstep.plan_slots_for` a shard); at least a shard's members, the whole shard is
    planned whenever one member asks and the result kept for those that did. A shard of more than
    ``agent.hints.whole_batch_plans`` members, or of more than ``agent.hints.whole_batch_bytes`` bytes of agent state,
    plans in rounds only. ``signature`` (:func:`signature` of its inputs) only keys the cache.
    """
    loop = lockstep.Loop(agent, variant, record_visits, plan_slots, bandwidth, stop_when_converged)
    chunk = functools.partial(lockstep.chunk, loop, capacity)
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


@functools.lru_cache(maxsize=MAX_CACHED_PROGRAMS)
def constants_program(variant: Variant, signature: tuple | None = None) -> Callable:
    """``constants(mdps, mdp_index) -> IndicatorConstants`` of every member (one per stacked MDP, gathered);
    ``signature`` (:func:`signature` of its inputs) only keys the cache."""

    # lax.map, not vmap: the constants come from planning loops run to convergence, and a vmapped while_loop runs
    # until its slowest member converges. The per-member gather is in the same program.
    def constants(mdps, mdp_index):
        unique = jax.lax.map(lambda m: indicator_constants(dynamics(m), variant), mdps)
        return jax.tree.map(lambda x: x[mdp_index], unique)

    return jax.jit(constants)
