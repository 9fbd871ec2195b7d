"""The interface between agents and the experiment runner (paper §3.3, App. A.1).

An agent is a bundle of pure functions on unbatched pytrees; the runner vmaps them over seeds, MDPs and
hyperparameter sets and drives them in lockstep:

* ``init(key, spec, hparams) -> state``;
* ``act(key, state, obs, h) -> action`` (``h`` is the in-episode step, or the steps since reset when continuous);
* ``update(state, transition) -> state``: the cheap per-step learning rule;
* ``needs_plan(state) -> bool``: whether an expensive planning step (a posterior sample and finite-horizon value
  iteration, extended value iteration, ...) must run before the next action, e.g. at an episode or epoch boundary;
* ``plan(key, state) -> state``: that planning step. The runner calls it inside a ``lax.cond`` whose predicate is
  "some member of the batch needs to plan" and keeps the result only for the members that do, so planning is paid
  only at boundaries instead of at every step (a ``cond`` inside a ``vmap`` would run it every step). Before the
  first action the runner plans every member, whatever ``needs_plan`` says (the reference's
  ``before_start_interacting``);
* ``policy(state) -> pi``: the agent's current best policy estimate, ``[S, A]`` (continuous) or ``[H, S, A]``
  (episodic), used only to compute expected regret;
* ``diagnostics(state) -> {name: int scalar}`` (optional): counters of silent degradation kept in the state, e.g.
  plans that stopped at their iteration cap; the runner writes each as a column of its per-record CSV and warns at
  the end of a run where one is non-zero.

``check_hparams`` validates hyperparameters on the host and ``observation`` says what ``obs`` is (below). Everything
else is in ``Agent.hints``, a :class:`RunnerHints`: how the runner may compute the same records faster. An agent
author can leave it at its defaults (the runner then makes no assumption), and set a field when the agent has the
property it names:

* ``greedy_actions(state) -> actions``: for an agent whose ``policy`` is always deterministic, the same policy as
  action indices, ``int32`` ``[S]`` or ``[H, S]`` (``policy`` is its one-hot form). The runner then compares and
  evaluates the indices instead of the ``[.., S, A]`` probabilities: ``A`` times less memory per log, and an
  episodic evaluation that reads only the chosen actions' successor lists (the same numbers).
* ``warm_policy(state, start) -> (policy, start')`` with ``policy_start(state) -> start``: ``policy`` computed from
  a warm start that the runner carries from one log to the next.
* ``fixed_policy``: ``policy`` is the same at every step of a run (it depends on no learnt quantity, as the random
  agent's). The runner then evaluates it at the first log and never builds or compares it again (the same records,
  with no per-log policy extraction; docs/performance.md, Tabular agents).
* ``act_apart``: the runner computes each step's action apart from the rest of the step, in a conditional that XLA
  does not fuse into the action's users (CPU only): for an ``act`` that reads rows of large per-member tables (the
  Q-learning agents), whose reads XLA would otherwise repeat in every fusion that uses the action.
* ``whole_batch_plans``, ``whole_batch_bytes`` and ``plan_slot_bytes``: how the runner groups the members that plan
  at the same step (:mod:`jaxmdp.experiment.planning`; docs/performance.md, Planning rounds).

What an agent observes is declared by ``Agent.observation``:

* ``"state"`` (tabular agents): ``obs`` is the state index, an ``int32`` scalar; such an agent rejects a BlockMDP;
* ``"emission"`` (deep agents, paper §3.1 and App. A.2): ``obs`` is the BlockMDP's observation of the state, the
  row of its emission table plus emission noise; ``spec.observations`` holds the noiseless table, ``[S, *obs]``
  (continuous) or ``[H, S, *obs]`` (episodic), on which ``policy`` evaluates the greedy action of every state;
* ``"any"``: the agent ignores ``obs`` (the random agent).

``Transition.obs`` and ``Transition.next_obs`` are then observations of the same kind; ``next_obs`` is the very
sample the agent acts on next (unless the episode ended), not a second noise draw.

Hyperparameters are a :mod:`jaxmdp.struct` pytree (or a ``flax.struct`` one) whose numeric fields are leaves, so a
grid can vmap over them; sizes are static. Agents must never choose an action outside ``spec.action_mask`` (padded
actions of a stacked batch).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, Literal

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp import struct
from jaxmdp.mdp import MDP

__all__ = ["MDPSpec", "Transition", "Agent", "RunnerHints", "spec_of", "plans_whole", "where_due"]


class MDPSpec(struct.PyTreeNode):
    """What an agent may know about the MDP it faces.

    ``n_states``, ``n_actions`` and ``H`` (time-array length, ``None`` when continuous) are static; ``horizon`` (the
    member's own episode length), the masks and ``n_steps`` (the optimisation horizon ``T``, total interaction steps)
    are traced, so one compiled program serves a stacked batch.
    """

    n_states: int = struct.field(pytree_node=False)
    n_actions: int = struct.field(pytree_node=False)
    H: int | None = struct.field(pytree_node=False)
    horizon: jax.Array
    state_mask: jax.Array
    action_mask: jax.Array
    n_steps: jax.Array
    #: The emission table of a BlockMDP (``[S, *obs]`` or ``[H, S, *obs]``); ``None`` for a plain MDP.
    observations: jax.Array | None = None
    #: ``None``, or a 0/1 array of one observation's shape (traced) marking the components the emission map fills;
    #: 0 marks padding, which is 0 in every observation (:func:`jaxmdp.pad_observations`).
    observation_mask: jax.Array | None = None
    #: Floating dtype of the MDP (static): tabular agents keep their tables in it.
    dtype: Any = struct.field(pytree_node=False, default=np.dtype("float32"))
    #: Length ``K`` of the MDP's successor lists (static): no pair has more than ``K`` next states of positive
    #: probability, so an agent may store its counts of observed next states in ``K`` slots per pair, a storage
    #: bound that changes none of its decisions. ``None`` (a spec built by hand) means no bound (``n_states``).
    max_successors: int | None = struct.field(pytree_node=False, default=None)
    #: A state order (``[S]``, traced) in which every transition of positive probability joins states at most
    #: ``bandwidth`` (static) positions apart (:func:`jaxmdp.gth.band_order`), or ``None``: a hint for an agent's
    #: linear algebra (banded instead of dense solves), like ``max_successors`` a bound that changes none of its
    #: decisions beyond rounding.
    state_order: jax.Array | None = None
    bandwidth: int | None = struct.field(pytree_node=False, default=None)

    @property
    def episodic(self) -> bool:
        return self.H is not None


def spec_of(
    mdp: MDP, n_steps: int | jax.Array, state_order: jax.Array | None = None, bandwidth: int | None = None
) -> MDPSpec:
    """The :class:`MDPSpec` of an (unbatched or stacked) MDP, or of a BlockMDP (any pytree with fields ``mdp`` and
    ``emissions``), for an interaction of ``n_steps`` steps; ``state_order`` and ``bandwidth``: the MDP's
    :func:`jaxmdp.gth.band_order`, both or neither (not checked here: an agent checks its use of them)."""
    if (state_order is None) != (bandwidth is None):
        raise ValueError("state_order and bandwidth go together: give both (jaxmdp.gth.band_order) or neither")
    observations = getattr(mdp, "emissions", None)
    observation_mask = getattr(mdp, "obs_mask", None)
    mdp = getattr(mdp, "mdp", mdp)
    return MDPSpec(
        n_states=mdp.n_states,
        n_actions=mdp.n_actions,
        H=mdp.H,
        horizon=mdp.horizon,
        state_mask=mdp.state_mask,
        action_mask=mdp.action_mask,
        n_steps=jnp.broadcast_to(jnp.asarray(n_steps, jnp.int32), mdp.horizon.shape),
        observations=observations,
        observation_mask=observation_mask,
        dtype=np.dtype(mdp.dtype),
        max_successors=mdp.max_successors,
        state_order=state_order,
        bandwidth=bandwidth,
    )


class Transition(struct.PyTreeNode):
    """One interaction step: ``obs --action--> next_obs`` with ``reward``, taken at in-episode step ``h``.

    ``next_obs`` is the state the action reached, also on the last step of an episode (``terminated``), where the
    environment then resets.
    """

    obs: jax.Array
    action: jax.Array
    reward: jax.Array
    next_obs: jax.Array
    h: jax.Array
    terminated: jax.Array


def _never_plans(state: Any) -> jax.Array:
    return jnp.zeros((), bool)


def _no_plan(key: jax.Array, state: Any) -> Any:
    return state


@dataclasses.dataclass(frozen=True)
class RunnerHints:
    """How the runner may compute an agent's records faster (see the module docstring); the defaults assume nothing.

    Every field is a property of the agent that the runner exploits without changing a record: an alternative form of
    ``policy`` (``greedy_actions``, ``warm_policy``/``policy_start``), a promise (``fixed_policy``) or a choice of how
    to compile and group the agent's work (``act_apart``, the planning limits)."""

    #: Optional ``state -> int32 [S] or [H, S]``: ``policy`` as action indices, when it is always deterministic.
    greedy_actions: Callable[[Any], jax.Array] | None = None
    #: Optional ``(state, start) -> (policy, start')``: ``policy(state)`` computed from a warm ``start`` (an array of
    #: the agent's choosing, e.g. the values of its previous estimate), and the start for the next call. The runner
    #: hands each log the ``start'`` of the previous one (``policy_start(state)`` before the first) and evaluates the
    #: policy it returns, which must be ``policy``'s estimate up to that estimate's own tolerances. Given with
    #: ``policy_start`` or not at all, and not with ``greedy_actions``; an agent made by ``dataclasses.replace`` with
    #: another ``policy`` must replace or clear both.
    warm_policy: Callable[[Any, jax.Array], tuple[jax.Array, jax.Array]] | None = None
    #: Optional ``state -> start``: the first ``start`` of ``warm_policy`` (from the state after ``init``).
    policy_start: Callable[[Any], jax.Array] | None = None
    #: True when ``policy`` is the same at every step of a run (it depends on no learnt quantity, as the random
    #: agent's): the runner then evaluates it at the first log only and never extracts or compares it again.
    fixed_policy: bool = False
    #: Whether the runner computes each step's action apart from the rest of the step (on CPU, in a conditional
    #: that XLA does not fuse into the action's users; :func:`jaxmdp.experiment.lockstep.apart`). For an ``act`` that
    #: reads rows of large per-member tables, whose reads XLA otherwise repeats in each fusion that uses the action
    #: (the Q-learning agents). For other agents the boundary costs a little or nothing, so it is off by default
    #: (docs/performance.md, Tabular agents).
    act_apart: bool = False
    #: The largest lockstep batch (a shard's members) that the runner plans whole, in one ``vmap``, when more than
    #: half its members ask at once (``None``: any); larger batches always plan in rounds of planning slots
    #: (:func:`jaxmdp.experiment.planning.plan_due`) and compile no whole-batch copy of ``plan``. 0 for an agent
    #: whose members seldom ask together (docs/performance.md, Planning rounds).
    whole_batch_plans: int | None = None
    #: The largest total size in bytes of a lockstep batch's agent states that the runner plans whole (``None``: any);
    #: a batch above it plans in rounds like one above ``whole_batch_plans``.
    whole_batch_bytes: int | None = None
    #: On a CPU, the most bytes of agent state that a planning round's slots hold together when the runner picks the
    #: slots itself (``plan_slots=None``): at most ``plan_slot_bytes // (one member's state bytes)`` slots, at least
    #: one (``None``: no cap; :func:`jaxmdp.experiment.planning.default_plan_slots`).
    plan_slot_bytes: int | None = None
    #: True when the members of a batch ask for a plan together (a schedule of step counts and shared
    #: hyperparameters, as the deep agents' gradient steps): the runner then plans the whole batch whenever one
    #: member asks, under one conditional, and compiles no planning rounds, whose gathers and scatters would move
    #: every member's state (a replay buffer) at each plan for nothing (docs/performance.md, Deep agents). The
    #: records are the same either way; a grid whose members ask at different steps (different ``sgd_period``)
    #: pays a whole batch of plans for each.
    plans_together: bool = False

    def __post_init__(self) -> None:
        if (self.warm_policy is None) != (self.policy_start is None):
            raise ValueError("RunnerHints: warm_policy and policy_start go together (one of them is None)")
        if self.warm_policy is not None and self.greedy_actions is not None:
            raise ValueError("RunnerHints: warm_policy is for agents without greedy_actions")


@dataclasses.dataclass(frozen=True, eq=False)
class Agent:
    """A named bundle of the interface functions (see the module docstring) and default hyperparameters.

    Agents compare and hash by identity (the runner caches compiled programs per agent): ``dataclasses.replace``
    (or :meth:`with_hints`) makes a new agent."""

    name: str
    episodic: bool
    default_hparams: Any
    init: Callable[[jax.Array, MDPSpec, Any], Any]
    act: Callable[[jax.Array, Any, jax.Array, jax.Array], jax.Array]
    update: Callable[[Any, Transition], Any]
    policy: Callable[[Any], jax.Array]
    needs_plan: Callable[[Any], jax.Array] = _never_plans
    plan: Callable[[jax.Array, Any], Any] = _no_plan
    #: Validates hyperparameters on the host (raises ``ValueError``); called by the runner before compiling.
    check_hparams: Callable[[Any], None] = lambda hparams: None
    #: What ``obs`` is: ``"state"`` (a state index), ``"emission"`` (a BlockMDP observation) or ``"any"``.
    observation: Literal["state", "emission", "any"] = "state"
    #: Optional ``state -> {name: int scalar}``: counters the runner records and warns about (module docstring).
    diagnostics: Callable[[Any], dict[str, jax.Array]] | None = None
    #: How the runner may compute the same records faster (:class:`RunnerHints`; the defaults assume nothing).
    hints: RunnerHints = RunnerHints()

    def __post_init__(self) -> None:
        if not isinstance(self.hints, RunnerHints):
            raise ValueError(f"agent {self.name!r}: hints must be a RunnerHints; got {type(self.hints).__name__}")

    @property
    def plans(self) -> bool:
        """Whether the agent has a planning step (``plan`` given); the runner compiles none for one without."""
        return self.plan is not _no_plan

    def with_hints(self, **changes: Any) -> "Agent":
        """A new agent with these fields of :attr:`hints` changed (``dataclasses.replace`` on both records)."""
        return dataclasses.replace(self, hints=dataclasses.replace(self.hints, **changes))


def batch_bytes(states: Any) -> tuple[int, int]:
    """``(members, bytes)`` of a lockstep batch of ``states`` (member axis first; arrays, tracers or
    ``jax.ShapeDtypeStruct``s: static shapes only)."""
    leaves = jax.tree.leaves(states)
    members = leaves[0].shape[0] if leaves else 0
    return members, sum(int(np.prod(x.shape)) * np.dtype(x.dtype).itemsize for x in leaves)


def plans_whole(agent: Agent, states: Any) -> bool:
    """Whether the runner may plan a lockstep batch of ``states`` (member axis first) whole: at most
    ``agent.hints.whole_batch_plans`` members and at most ``agent.hints.whole_batch_bytes`` bytes of state (static
    shapes)."""
    members, nbytes = batch_bytes(states)
    hints = agent.hints
    return ((hints.whole_batch_plans is None or members <= hints.whole_batch_plans)
            and (hints.whole_batch_bytes is None or nbytes <= hints.whole_batch_bytes))


def where_due(due: jax.Array, new: Any, old: Any) -> Any:
    """``new`` where ``due`` else ``old``, leaf by leaf: the keep-where-due merge of planning.

    ``due`` is a boolean scalar (one member: an agent's ``plan`` applies it to itself, so that a plan requested by a
    member that does not need one is a no-op whoever calls it) or ``[B]`` over the leading member axis of every leaf
    (the runner, which plans a batch of members and keeps the result only for those that asked: all members when
    most asked, else rounds of those that did, :mod:`jaxmdp.experiment.planning`). With a scalar ``due``, a leaf that
    ``new`` takes from ``old`` unchanged (the same object) is returned as it is, so that the rounds do not write it
    back. Over a batch every leaf is selected: XLA simplifies the select of a leaf with itself, while the leaf
    returned as it is from the runner's planning conditional made XLA copy a deep agent's replay buffer twice at every
    step (docs/performance.md, Deep agents).
    """
    due = jnp.asarray(due)

    def merge(n, o):
        if n is o and due.ndim == 0:
            return o
        return jnp.where(due if due.ndim == 0 else due.reshape(due.shape + (1,) * (n.ndim - due.ndim)), n, o)

    return jax.tree.map(merge, new, old)
