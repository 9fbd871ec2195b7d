"""Hyperparameter search spaces of the agents and random-search candidates (paper App. D, App. F).

Each space is the reference's (docs/agents.md, "Search space" of every agent): independent uniform ranges over
the named numeric fields of a tabular agent's hyperparameter pytree (:data:`SEARCH_SPACES`), or, for the deep
agents, uniform choices among listed values (:data:`CHOICE_SPACES`, the reference's ``tune.choice``); every other
field keeps its default. Candidates are drawn with ``jax.random`` from an explicit key (same key, same candidates)
and are returned as one stacked pytree, so a whole search runs as one lockstep grid (:func:`jaxmdp.experiment.runner.grid`).
A deep agent's space also varies static sizes (network width and depth, batch size, ensemble size), which shape
arrays: its candidates form one grid per distinct static configuration (:func:`sample_candidate_groups`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import jax
import numpy as np

from jaxmdp._checks import check_int
from jaxmdp.experiment.agent_interface import Agent

__all__ = ["SEARCH_SPACES", "CHOICE_SPACES", "search_space", "check_space", "sample_candidates",
           "sample_candidate_groups"]

#: Agent name -> ``{field: (low, high)}``: the shipped agents' uniform ranges of docs/agents.md, then those given to
#: :func:`agents.register` (a read-only view of the registry's spaces).
_RANGES: dict[str, Mapping[str, tuple[float, float]]] = dict(
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
    }
)
SEARCH_SPACES: Mapping[str, Mapping[str, tuple[float, float]]] = MappingProxyType(_RANGES)
_SHIPPED_RANGES = frozenset(_RANGES)

_Q_NETWORK_CHOICES = {
    "network_width": (64, 128, 256),
    "network_depth": (2, 4),
    "batch_size": (32, 64, 128),
    "sgd_period": (1, 4, 8),
    "target_update_period": (4, 16, 32),
}
_DQN_CHOICES = MappingProxyType({**_Q_NETWORK_CHOICES, "epsilon": (0.01, 0.05, 0.1)})
_BOOT_DQN_CHOICES = MappingProxyType(
    {**_Q_NETWORK_CHOICES, "mask_prob": (0.8, 0.9, 1.0), "noise_scale": (0.0, 0.05, 0.1), "n_ensemble": (8, 16, 20)}
)

_ACTOR_CRITIC_CHOICES = MappingProxyType(
    {"width": (64, 128, 256), "depth": (2, 4), "max_sequence_length": (16, 32, 64, 128), "td_lambda": (0.7, 0.8, 0.9)}
)

#: Agent name -> ``{field: values}``, the deep agents' ``tune.choice`` spaces of agents.md §7 (uniform over values).
CHOICE_SPACES: Mapping[str, Mapping[str, tuple[float, ...]]] = MappingProxyType(
    {
        "dqn_episodic": _DQN_CHOICES,
        "dqn_continuous": _DQN_CHOICES,
        "boot_dqn_episodic": _BOOT_DQN_CHOICES,
        "boot_dqn_continuous": _BOOT_DQN_CHOICES,
        **{
            f"{name}_{setting}": _ACTOR_CRITIC_CHOICES
            for name in ("actor_critic", "actor_critic_rnn")
            for setting in ("episodic", "continuous")
        },
    }
)


def search_space(agent: Agent | str) -> Mapping[str, tuple[float, ...]]:
    """The search space of ``agent`` (an :class:`Agent` or its name): ``{field: (low, high)}`` (uniform range) or,
    for a deep agent, ``{field: values}`` (uniform choice); ``ValueError`` if it has none."""
    name = agent if isinstance(agent, str) else agent.name
    for spaces in (SEARCH_SPACES, CHOICE_SPACES):
        if name in spaces:
            return spaces[name]
    raise ValueError(
        f"agent {name!r} has no search space; agents with one: {', '.join([*SEARCH_SPACES, *CHOICE_SPACES])}"
    )


def check_space(agent: Agent, space: Mapping[str, Any]) -> Mapping[str, tuple[float, float]]:
    """``space`` checked as a search space of ``agent`` (the tuner's format, :data:`SEARCH_SPACES`) and returned
    read-only: a non-empty mapping from fields of ``agent.default_hparams`` that are numeric scalar leaves (not
    static) to ``(low, high)`` with finite ``low < high``. ``ValueError`` naming the field otherwise."""
    if not isinstance(space, Mapping) or not space:
        raise ValueError(f"search_space of {agent.name!r} must be a non-empty mapping {{field: (low, high)}}; got "
                         f"{space!r}")
    default = agent.default_hparams
    if not dataclasses.is_dataclass(default):
        raise ValueError(f"search_space of {agent.name!r}: its default_hparams must be a jaxmdp.struct (or flax.struct) "
                         "dataclass")
    fields = {f.name for f in dataclasses.fields(default)}
    static = _static_fields(default)
    out = {}
    for field, bounds in space.items():
        if field not in fields:
            raise ValueError(f"search_space of {agent.name!r} names {field!r}, not a field of its hyperparameters "
                             f"({', '.join(sorted(fields))})")
        if field in static:
            raise ValueError(f"search_space of {agent.name!r}: field {field!r} is static (it shapes arrays); the tuner "
                             "searches numeric leaves only")
        if np.ndim(getattr(default, field)) != 0 or not np.issubdtype(np.asarray(getattr(default, field)).dtype,
                                                                      np.number):
            raise ValueError(f"search_space of {agent.name!r}: field {field!r} must hold a numeric scalar")
        try:
            low, high = (float(b) for b in bounds)
        except (TypeError, ValueError):
            raise ValueError(f"search_space of {agent.name!r}: {field!r} must map to (low, high); got "
                             f"{bounds!r}") from None
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise ValueError(f"search_space of {agent.name!r}: {field!r} needs finite low < high; got {bounds!r}")
        out[field] = (low, high)
    return MappingProxyType(out)


def _set_space(name: str, space: Mapping[str, tuple[float, float]] | None) -> None:
    """Set (or, with ``None``, remove) the search space of a registered agent (:func:`agents.register`)."""
    if name in _SHIPPED_RANGES or name in CHOICE_SPACES:
        raise ValueError(f"the search space of the shipped agent {name!r} is fixed")
    if space is None:
        _RANGES.pop(name, None)
    else:
        _RANGES[name] = space


def _static_fields(hparams: Any) -> set[str]:
    return {f.name for f in dataclasses.fields(hparams) if f.metadata.get("pytree_node", True) is False}


def _draw(agent: Agent, key: jax.Array, n: int, include_default: bool) -> dict[str, np.ndarray]:
    """``{field: [n] values}`` for every field of the agent's space (see :func:`sample_candidates`)."""
    n = check_int("n", n)
    name = agent.name
    default = agent.default_hparams
    draws = {}
    for j, (field, domain) in enumerate(search_space(agent).items()):
        u = np.asarray(jax.random.uniform(jax.random.fold_in(key, j), (n,)), np.float64)
        if name in CHOICE_SPACES:
            choices = np.asarray(domain)
            values = choices[np.minimum((u * len(choices)).astype(np.int64), len(choices) - 1)]
        else:
            low, high = domain
            values = low + (high - low) * u
        if include_default:
            values[0] = getattr(default, field)
        draws[field] = values
    return draws


def sample_candidates(agent: Agent, key: jax.Array, n: int, *, include_default: bool = True) -> Any:
    """``n`` hyperparameter sets, stacked along a leading axis (numpy leaves).

    Field ``f`` of candidate ``i`` is ``low_f + (high_f - low_f) u`` (a range) or ``values_f[floor(len u)]`` (a
    choice) with ``u = uniform(fold_in(key, f's index))[i]``; fields outside the search space keep their defaults.
    With ``include_default`` candidate 0 is the agent's default set (the benchmark's tuned values), so a search
    never does worse than the defaults on its objective. A space that varies static fields raises ``ValueError``:
    use :func:`sample_candidate_groups`.
    """
    static = sorted(_static_fields(agent.default_hparams) & set(search_space(agent)))
    if static:
        raise ValueError(
            f"the search space of {agent.name!r} varies static fields ({', '.join(static)}), which shape arrays: "
            "its candidates need one grid per configuration; use sample_candidate_groups"
        )
    return _stacked(agent.default_hparams, _draw(agent, key, n, include_default), np.arange(n))


def _stacked(default: Any, draws: dict[str, np.ndarray], index: np.ndarray) -> Any:
    stacked = jax.tree.map(lambda x: np.repeat(np.asarray(x)[None], len(index), axis=0), default)
    return stacked.replace(**{field: values[index] for field, values in draws.items()})


def sample_candidate_groups(
    agent: Agent, key: jax.Array, n: int, *, include_default: bool = True
) -> list[tuple[np.ndarray, Any]]:
    """The ``n`` candidates of :func:`sample_candidates` (same draws), grouped by their static fields: a list of
    ``(candidate indices, stacked hyperparameters)``, one per distinct static configuration, in order of first
    appearance; each group runs as one grid (one compiled program)."""
    default = agent.default_hparams
    draws = _draw(agent, key, n, include_default)
    static = [f for f in draws if f in _static_fields(default)]
    configs = [tuple(int(draws[f][i]) for f in static) for i in range(n)]
    groups = []
    for config in dict.fromkeys(configs):
        index = np.asarray([i for i in range(n) if configs[i] == config])
        traced = {f: v for f, v in draws.items() if f not in static}
        groups.append((index, _stacked(default.replace(**dict(zip(static, config))), traced, index)))
    return groups
