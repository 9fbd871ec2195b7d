"""The doubling-trick epoch schedule of UCRL2 and optimistic PSRL (Jaksch et al. 2010; Agrawal & Jia 2017).

An epoch ends as soon as the pair just played has been visited in the epoch as often as before it:
``nu(s, a) >= max(1, N_k(s, a))``, where ``nu`` counts visits in the current epoch and ``N_k = N - nu`` those
before it (``N`` the total, current step included). Equivalently ``N(s, a) >= 2 N_k(s, a)`` once the pair has been
seen; in particular the first visit of a pair ends its epoch. This is the rule of the reference (docs/agents.md §3, §4),
checked after each step on the pair just played. Jaksch et al. check it *before* acting instead (the epoch ends when
the policy asks for a pair whose count has doubled). Jaksch et al.'s bound on the number of epochs,
``S A log2(8 T / (S A))`` (their Prop. 18), holds for both: every epoch but the last ends with a pair whose visits in the
epoch reached ``max(1, N_k)``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmdp import struct

__all__ = ["EpochSchedule", "epoch_schedule", "record_visit", "start_epoch"]


class EpochSchedule(struct.PyTreeNode):
    """Visit counters: ``visits[s, a]`` in total (``N``) and ``epoch_visits[s, a]`` in the current epoch (``nu``)."""

    visits: jax.Array
    epoch_visits: jax.Array


def epoch_schedule(n_states: int, n_actions: int) -> EpochSchedule:
    """Counters of a fresh agent: no visits, first epoch."""
    zeros = jnp.zeros((n_states, n_actions), jnp.int32)
    return EpochSchedule(visits=zeros, epoch_visits=zeros)


def record_visit(schedule: EpochSchedule, s: jax.Array, a: jax.Array) -> tuple[EpochSchedule, jax.Array]:
    """Count a visit of ``(s, a)``; returns the counters and whether the epoch ends (``nu >= max(1, N - nu)``)."""
    n = schedule.visits[s, a] + 1
    nu = schedule.epoch_visits[s, a] + 1
    new = EpochSchedule(visits=schedule.visits.at[s, a].set(n), epoch_visits=schedule.epoch_visits.at[s, a].set(nu))
    return new, nu >= jnp.maximum(1, n - nu)


def start_epoch(schedule: EpochSchedule) -> EpochSchedule:
    """Reset the in-epoch counters ``nu`` (called when the agent re-plans)."""
    return schedule.replace(epoch_visits=jnp.zeros_like(schedule.epoch_visits))
