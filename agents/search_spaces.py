"""Hyperparameter search spaces of the agents and random-search candidates (paper App. D, App. F).

Each space is the reference's (spec ``agents.md``, "Search space" of every agent): independent uniform ranges over
the named numeric fields of the agent's hyperparameter pytree; every other field keeps its default. Candidates are
drawn with ``jax.random`` from an explicit key (same key, same candidates) and are returned as one stacked pytree,
so a whole search runs as one lockstep grid (:func:`jaxmdp.runner.grid`).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import jax
import numpy as np

from jaxmdp.agent_interface import Agent

__all__ = ["SEARCH_SPACES", "SIZE_CHOICES", "search_space", "sample_candidates"]

_ACTOR_CRITICS = (
    "actor_critic_episodic", "actor_critic_continuous", "actor_critic_rnn_episodic", "actor_critic_rnn_continuous"
)

#: Agent name -> ``{field: (low, high)}``, uniform ranges of agents.md.
SEARCH_SPACES: Mapping[str, Mapping[str, tuple[float, float]]] = MappingProxyType(
    {
        "psrl_episodic": MappingProxyType({"prior_mean": (0.001, 2.0), "transition_prior": (0.001, 2.0)}),
        "q_learning_episodic": MappingProxyType(
            {"c_1": (0.001, 1.1), "c_2": (0.001, 1.1), "min_at": (0.001, 0.2)}
        ),
        "ucrl2": MappingProxyType({"alpha_p": (0.1, 3.0), "alpha_r": (0.1, 3.0)}),
        "psrl_continuous": MappingProxyType(
            {
                "psi_weight": (0.001, 0.1),
                "omega_weight": (0.0001, 1.0),
                "kappa_weight": (0.2, 4.0),
                "eta_weight": (1e-10, 1e-6),
                "rewards_prior_mean": (0.0, 1.2),
            }
        ),
        "q_learning_continuous": MappingProxyType(
            {"h_weight": (0.001, 1.1), "span_approx_weight": (0.001, 1.1), "min_at": (0.001, 0.2)}
        ),
        # The actor-critics (agents.md §7): the reference chooses td_lambda in {0.7, 0.8, 0.9}; here the range
        # that covers those choices. Their static sizes are in SIZE_CHOICES.
        **{name: MappingProxyType({"td_lambda": (0.7, 0.9)}) for name in _ACTOR_CRITICS},
    }
)

#: Agent name -> ``{static size: choices}`` of agents.md §7. Sizes shape arrays, so a grid cannot vmap over them:
#: :func:`sample_candidates` leaves them at their defaults, and a search over them runs one grid per combination.
SIZE_CHOICES: Mapping[str, Mapping[str, tuple[int, ...]]] = MappingProxyType(
    {
        name: MappingProxyType(
            {"width": (64, 128, 256), "depth": (2, 4), "max_sequence_length": (16, 32, 64, 128)}
        )
        for name in _ACTOR_CRITICS
    }
)


def search_space(agent: Agent | str) -> Mapping[str, tuple[float, float]]:
    """The search space of ``agent`` (an :class:`Agent` or its name); ``ValueError`` if it has none."""
    name = agent if isinstance(agent, str) else agent.name
    if name not in SEARCH_SPACES:
        raise ValueError(f"agent {name!r} has no search space; agents with one: {', '.join(SEARCH_SPACES)}")
    return SEARCH_SPACES[name]


def sample_candidates(agent: Agent, key: jax.Array, n: int, *, include_default: bool = True) -> Any:
    """``n`` hyperparameter sets, stacked along a leading axis (numpy leaves).

    Field ``f`` of candidate ``i`` is ``low_f + (high_f - low_f) u`` with ``u = uniform(fold_in(key, f's index))[i]``;
    fields outside the search space keep their defaults. With ``include_default`` candidate 0 is the agent's
    default set (the benchmark's tuned values), so a search never does worse than the defaults on its objective.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1; got {n!r}")
    space = search_space(agent)
    default = agent.default_hparams
    updates = {}
    for j, (field, (low, high)) in enumerate(space.items()):
        u = np.asarray(jax.random.uniform(jax.random.fold_in(key, j), (n,)), np.float64)
        values = low + (high - low) * u
        if include_default:
            values[0] = float(getattr(default, field))
        updates[field] = values
    stacked = jax.tree.map(lambda x: np.repeat(np.asarray(x)[None], n, axis=0), default)
    return stacked.replace(**updates)
