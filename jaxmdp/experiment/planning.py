"""Planning only the members that asked: the runner's compacted planning step (paper App. A.1, "lockstep").

The agents that plan (PSRL at every episode start, UCRL2 and continuous PSRL at their epoch ends) ask for a plan at
different steps, member by member: in a benchmark batch whose members have different horizons or epoch schedules,
some member asks at almost every step. Planning the whole batch ``B`` whenever one member asks (and keeping the
result only for those that did) then costs a full batch of plans per step. :func:`plan_due` instead gathers the
members that asked into ``slots`` planning slots (:func:`jaxmdp.sampling.compaction.compact`), plans those under
``vmap`` (one slot: one plain call), scatters the plans back and repeats until every member that asked has its plan;
the cost is ``ceil(m / slots)`` rounds of ``slots`` plans for ``m`` members asking, whatever ``B`` (one batch of ``B``
when more than half ask and ``B`` is at most the agent's ``whole_batch_plans``).

Each member plans with its own key and its own state, exactly as in the whole-batch step, and the agents' plans
(their samplers included, :mod:`jaxmdp.sampling.beta_sampling`) give a member the same bits whoever else is in the
``vmap``-ed batch, so the runner's results do not depend on ``slots`` (tested in tests/test_runner_planning.py).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

from jaxmdp.experiment.agent_interface import where_due
from jaxmdp.sampling.compaction import compact

__all__ = ["plan_due", "default_plan_slots"]


def default_plan_slots(n_members: int, member_bytes: int = 0, slot_bytes: int | None = None) -> int:
    """Planning slots for a lockstep loop of ``n_members`` members: ``ceil(n_members / 16)``, and with ``slot_bytes``
    at most ``slot_bytes // member_bytes`` (``member_bytes``: one member's agent state), at least one.

    The cap is for a plan whose working set grows with the state it reads (episodic PSRL's Dirichlet draws over its
    dense counts): on a CPU, slots whose states no longer fit the caches together plan slower than fewer slots in more
    rounds (docs/performance.md, Planning rounds).
    ``slot_bytes = 0`` plans one member a round."""
    slots = max(1, -(-n_members // 16))
    if slot_bytes is not None and member_bytes > 0:
        slots = min(slots, max(1, slot_bytes // member_bytes))
    return slots


def plan_due(
    plan: Callable[[jax.Array, Any], Any],
    slots: int,
    due: jax.Array,
    keys: jax.Array,
    states: Any,
    whole_batch: bool = True,
    lone_rounds: bool = True,
) -> Any:
    """``plan(keys[i], states[i])`` for every member ``i`` with ``due[i]``, ``states[i]`` for the others.

    ``due`` is ``bool[B]``, ``keys`` ``[B]`` keys and ``states`` a pytree with the member axis first. Rounds of
    ``slots`` members (static): each round plans the first ``slots`` members still waiting (an empty slot repeats the
    round's first member, whose copy is dropped) and scatters their plans back; the rounds go on until none waits, so
    the result does not depend on ``slots``. ``lone_rounds`` (static): a round with one member waiting plans it alone
    (a second, one-slot copy of ``plan``): late in a continuous run, where epochs end member by member, most rounds
    are such, and on a CPU a round of several slots costs several times a round of one (a vmapped plan waits for its
    slowest slot; docs/performance.md, Continuous planning). The runner leaves it off for episodic agents, whose members
    of one MDP end their episodes together: there it seldom runs and costs compile time. When more than half the
    members wait, all ``B`` are planned in one batch instead (the result kept where due): a round has a fixed cost
    (the plan's loops and their dispatch), so when every member's episode ends at the same step (one MDP, many seeds)
    many rounds of small plans cost more than one batch. ``whole_batch=False`` (static) always plans in rounds and
    compiles no whole-batch copy of ``plan``: for large batches, whose rounds of ``slots`` plans are at least as fast
    (a whole batch's working set leaves the caches), and for agents whose members seldom ask together.
    """

    def alone(k, st):
        # One slot's plan without vmap: the same bits as a vmap of one (tests/test_runner_planning.py), and its loops'
        # predicates and gathers unbatched compile faster (docs/performance.md, Plan slots). A leaf the plan passes
        # through stays the slot's own leaf, so that ``put`` sees it unchanged.
        st0 = jax.tree.map(lambda x: x[0], st)
        return jax.tree.map(lambda y, x0, x: x if y is x0 else y[None], plan(k[0], st0), st0, st)

    def plan_slots(k, st, valid):
        if slots == 1:
            return alone(k, st)
        if not lone_rounds:
            return jax.vmap(plan)(k, st)

        # A lone member waiting is planned alone, not with slots - 1 copies of itself. Only the slots' states pass
        # through the cond: with the batch's in it, XLA copied them at every round.
        def one(k, st):
            lone = alone(k[:1], jax.tree.map(lambda x: x[:1], st))
            return jax.tree.map(lambda y: jnp.broadcast_to(y, (slots,) + y.shape[1:]), lone)

        return jax.lax.cond(jnp.sum(valid) == 1, one, jax.vmap(plan), k, st)

    def round_(carry):
        states, waiting = carry
        index, valid = compact(waiting, slots)  # empty slots hold B + s: distinct and dropped by the scatter
        take = jnp.where(valid, index, index[0])
        taken = jax.tree.map(lambda x: x[take], states)
        planned = plan_slots(keys[take], taken, valid)

        def put(x, t, y):
            # A leaf the plan passes through (``y is t``, e.g. episodic PSRL's dense counts) is not written back:
            # the write changes nothing, and with one slot XLA made it a dynamic-update-slice of the batch's leaf
            # from itself and copied the whole leaf twice per round (docs/performance.md, Planning rounds). Through
            # the lone-round ``cond`` every leaf is a new value and is written back: the continuous agents' states it
            # serves are small.
            return x if y is t else x.at[index].set(y, mode="drop", unique_indices=True)

        return (jax.tree.map(put, states, taken, planned),
                waiting.at[index].set(False, mode="drop", unique_indices=True))

    def rounds(states):
        return jax.lax.while_loop(lambda carry: jnp.any(carry[1]), round_, (states, due))[0]

    def whole(states):
        return where_due(due, jax.vmap(plan)(keys, states), states)

    if not whole_batch:
        return rounds(states)
    return jax.lax.cond(2 * jnp.sum(due) > due.shape[0], whole, rounds, states)
