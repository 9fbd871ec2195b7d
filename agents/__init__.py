"""Agents as pure functions over pytrees (paper §3.3; docs/agents.md): the tabular agents and the deep agents of
:mod:`agents.deep` (which observe a BlockMDP's emissions).

``AGENTS`` maps each registered agent's name to its :class:`jaxmdp.experiment.agent_interface.Agent`; :func:`get`
looks one up, :func:`names` lists them by setting and observation, and :func:`register` adds your own (after which
the benchmark, ``jaxmdp-benchmark run --agents NAME``, and the tuner know it; docs/guide/own_agent.md).

The deep agents are imported when one is first asked for (``get``, ``AGENTS[name]``, iterating over
``AGENTS.values()``, or ``from agents import DQN_EPISODIC``), not by ``import agents``: they need flax's networks,
distrax and flashbax, which an MDP or a tabular agent never uses. Their names, settings and observations are known
without importing them, so :func:`names` and iterating over ``AGENTS``'s names import nothing.

Variants (the vocabulary of :data:`jaxmdp._checks.VARIANTS`): every agent follows its algorithm's paper
(``"paper"``, the default); ``COLOSSEUM_AGENTS`` holds the tabular agents with the reference package's update rules
instead (``"colosseum"``, docs/agents.md "Reference mode"), each a separate agent (its own compiled program) named
``<name>@colosseum``. The random agents are the same in both variants.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Iterator, Mapping
from typing import Any

from agents.psrl_continuous import PSRL_CONTINUOUS, PSRL_CONTINUOUS_COLOSSEUM
from agents.psrl_episodic import PSRL_EPISODIC, PSRL_EPISODIC_COLOSSEUM
from agents.q_learning_continuous import Q_LEARNING_CONTINUOUS, Q_LEARNING_CONTINUOUS_COLOSSEUM
from agents.q_learning_episodic import Q_LEARNING_EPISODIC, Q_LEARNING_EPISODIC_COLOSSEUM
from agents.random_agent import RANDOM_CONTINUOUS, RANDOM_EPISODIC
from agents.ucrl2 import UCRL2, UCRL2_COLOSSEUM
from jaxmdp._checks import VARIANTS, Variant, check_variant, did_you_mean
from jaxmdp.experiment.agent_interface import Agent


@dataclasses.dataclass(frozen=True)
class _Deferred:
    """A deep agent not yet imported: where it lives and what :func:`names` needs to know about it."""

    module: str
    attribute: str
    episodic: bool
    observation: str = "emission"

    def load(self) -> Agent:
        try:
            module = importlib.import_module(self.module)
        except ModuleNotFoundError as e:  # flax, optax, distrax or flashbax: the [deep] extra
            raise ModuleNotFoundError(
                f"the deep agents need the optional dependencies of the [deep] extra ({e.name} is missing): "
                "pip install 'jaxmdp-hardness[deep]'", name=e.name) from e
        return getattr(module, self.attribute)


def _deep(module: str, constant: str) -> dict[str, _Deferred]:
    """The episodic and continuous agents ``<CONSTANT>_EPISODIC``, ``<CONSTANT>_CONTINUOUS`` of ``agents.deep.<module>``,
    registered as ``<module>_episodic`` and ``<module>_continuous``."""
    return {f"{module}_{setting}": _Deferred(f"agents.deep.{module}", f"{constant}_{setting.upper()}",
                                              setting == "episodic")
            for setting in ("episodic", "continuous")}


_DEEP: dict[str, _Deferred] = {
    **_deep("dqn", "DQN"),
    **_deep("boot_dqn", "BOOT_DQN"),
    **_deep("actor_critic", "ACTOR_CRITIC"),
    **_deep("actor_critic_rnn", "ACTOR_CRITIC_RNN"),
}
#: ``from agents import DQN_EPISODIC`` and the like: the deep agents' constants, imported on use (module __getattr__).
_DEEP_CONSTANTS: dict[str, _Deferred] = {d.attribute: d for d in _DEEP.values()}


class Registry(Mapping[str, Agent]):
    """Name -> agent, in registration order; a deep agent is imported when its value is first read (module
    docstring). Read-only as a mapping: add agents with :func:`register`."""

    def __init__(self, entries: Mapping[str, Agent | _Deferred]):
        self._entries: dict[str, Agent | _Deferred] = dict(entries)

    def __getitem__(self, name: str) -> Agent:
        entry = self._entries[name]
        if isinstance(entry, _Deferred):
            entry = entry.load()
            self._entries[name] = entry
        return entry

    def __iter__(self) -> Iterator[str]:
        return iter(list(self._entries))

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __repr__(self) -> str:
        return f"Registry({', '.join(self._entries)})"

    def _describe(self, name: str) -> tuple[bool, str]:
        """``(episodic, observation)`` of ``name`` without importing it."""
        entry = self._entries[name]
        return entry.episodic, entry.observation

    def _add(self, agent: Agent) -> None:
        self._entries[agent.name] = agent


AGENTS: Registry = Registry({
    **{a.name: a for a in (RANDOM_EPISODIC, RANDOM_CONTINUOUS, Q_LEARNING_EPISODIC, Q_LEARNING_CONTINUOUS,
                           PSRL_EPISODIC, PSRL_CONTINUOUS, UCRL2)},
    **_DEEP,
})

#: The names of the agents this package ships (:func:`register` adds others to :data:`AGENTS` only).
SHIPPED: tuple[str, ...] = tuple(AGENTS)

#: The tabular agents with the reference's update rules, by their registry name (module docstring).
COLOSSEUM_AGENTS: dict[str, Agent] = {
    name: agent
    for name, agent in (
        ("random_episodic", RANDOM_EPISODIC),
        ("random_continuous", RANDOM_CONTINUOUS),
        ("q_learning_episodic", Q_LEARNING_EPISODIC_COLOSSEUM),
        ("q_learning_continuous", Q_LEARNING_CONTINUOUS_COLOSSEUM),
        ("psrl_episodic", PSRL_EPISODIC_COLOSSEUM),
        ("psrl_continuous", PSRL_CONTINUOUS_COLOSSEUM),
        ("ucrl2", UCRL2_COLOSSEUM),
    )
}


def get(name: str, variant: Variant = "paper") -> Agent:
    """The registered agent ``name`` in ``variant`` (``"paper"`` or ``"colosseum"``, module docstring); a name
    ``"<name>@colosseum"`` (a reference-mode agent's own name) selects that variant. ``ValueError`` with the closest
    names when unknown, or when the agent has no such variant (the deep agents and registered agents have only
    ``"paper"``)."""
    check_variant(variant)
    base, at, suffix = name.partition("@")
    if at:
        if suffix not in VARIANTS or (variant != "paper" and variant != suffix):
            raise ValueError(f"agent name {name!r}: the part after '@' must be a variant {VARIANTS} (not also another "
                             f"variant={variant!r})")
        name, variant = base, suffix
    if name not in AGENTS:
        raise ValueError(f"unknown agent {name!r}{did_you_mean(name, list(AGENTS), 0.5)} Registered: "
                         f"{', '.join(AGENTS)}")
    if variant == "paper":
        return AGENTS[name]
    if name not in COLOSSEUM_AGENTS:
        raise ValueError(f"agent {name!r} has no {variant!r} variant (reference mode); those that have one: "
                         f"{', '.join(COLOSSEUM_AGENTS)}")
    return COLOSSEUM_AGENTS[name]


_OBSERVATIONS = ("state", "emission", "any")


def names(*, episodic: bool | None = None, observations: tuple[str, ...] | None = None) -> list[str]:
    """The registered agents' names in registration order, those of one setting (``episodic``) and observing one of
    ``observations`` (``"state"``, ``"emission"``, ``"any"``; ``None``: every agent), without importing a deep
    agent."""
    if episodic is not None and not isinstance(episodic, bool):
        raise ValueError(f"episodic must be True, False or None; got {episodic!r}")
    if observations is not None and (isinstance(observations, str) or not set(observations) <= set(_OBSERVATIONS)):
        raise ValueError(f"observations must be a tuple of {_OBSERVATIONS} or None; got {observations!r}")
    out = []
    for name in AGENTS:
        ep, obs = AGENTS._describe(name)
        if (episodic is None or ep == episodic) and (observations is None or obs in observations):
            out.append(name)
    return out


def register(agent: Agent, search_space: Mapping[str, tuple[float, float]] | None = None, *,
             replace: bool = False) -> Agent:
    """Add ``agent`` to :data:`AGENTS` under ``agent.name`` (so :func:`get`, the benchmark and the tuner know it);
    returns it.

    ``search_space``: the tuner's random-search space, ``{field: (low, high)}`` uniform ranges over numeric fields of
    ``agent.default_hparams`` (the format of :data:`agents.search_spaces.SEARCH_SPACES`; ``jaxmdp-benchmark tune``
    draws every field as ``U(low, high)``); ``None``: the agent is not tuned (it runs with its defaults).
    Registering the same agent object again is allowed (an import that runs twice); a different agent under a
    registered name raises ``ValueError`` unless ``replace`` (a shipped agent can never be replaced), as do a
    non-Agent and a name with ``'@'``, ``':'`` or white space (those separate variants and module paths)."""
    from agents import search_spaces

    if not isinstance(agent, Agent):
        raise ValueError(f"agent must be a jaxmdp.agent_interface.Agent; got {type(agent).__name__}")
    name = agent.name
    if not isinstance(name, str) or not name or any(c in name for c in "@: \t\n/"):
        raise ValueError(f"agent.name must be a non-empty string without '@', ':', '/' or white space; got {name!r}")
    if not isinstance(replace, bool):
        raise ValueError(f"replace must be True or False; got {replace!r}")
    if agent.observation not in _OBSERVATIONS:
        raise ValueError(f"agent {name!r}: observation must be one of {_OBSERVATIONS}; got {agent.observation!r}")
    same = AGENTS._entries.get(name) is agent
    if name in SHIPPED and not (same and search_space is None):
        raise ValueError(f"agent name {name!r} is a shipped agent's (its search space is fixed); give your agent "
                         "another name")
    if name in AGENTS and not same and not replace:
        raise ValueError(f"an agent named {name!r} is already registered; pass replace=True to replace it, or give "
                         "your agent another name")
    if same and search_space is None:
        return agent  # registered again (the module imported twice, or by its module and the command line)
    space = None if search_space is None else search_spaces.check_space(agent, search_space)
    AGENTS._add(agent)
    search_spaces._set_space(name, space)
    return agent


def __getattr__(name: str) -> Any:
    # `agents.DQN_EPISODIC` and `from agents import DQN_EPISODIC`: the deep agents, imported on first use.
    deferred = _DEEP_CONSTANTS.get(name)
    if deferred is None:
        raise AttributeError(f"module 'agents' has no attribute {name!r}")
    return deferred.load()


__all__ = ["AGENTS", "COLOSSEUM_AGENTS", "SHIPPED", "Registry", "get", "names", "register"]
