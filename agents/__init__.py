"""Agents as pure functions over pytrees (paper §3.3; docs/agents.md): the tabular agents and the deep agents of
:mod:`agents.deep` (which observe a BlockMDP's emissions).

``AGENTS`` maps each agent's name to its :class:`jaxmdp.experiment.agent_interface.Agent`; :func:`get` looks one up.

Variants (the vocabulary of :data:`jaxmdp._checks.VARIANTS`): every agent follows its algorithm's paper
(``"paper"``, the default); ``COLOSSEUM_AGENTS`` holds the tabular agents with the reference package's update rules
instead (``"colosseum"``, docs/agents.md "Reference mode"), each a separate agent (its own compiled program) named
``<name>@colosseum``. The random agents are the same in both variants.
"""

from __future__ import annotations

from agents.deep.actor_critic import ACTOR_CRITIC_CONTINUOUS, ACTOR_CRITIC_EPISODIC
from agents.deep.actor_critic_rnn import ACTOR_CRITIC_RNN_CONTINUOUS, ACTOR_CRITIC_RNN_EPISODIC
from agents.deep.boot_dqn import BOOT_DQN_CONTINUOUS, BOOT_DQN_EPISODIC
from agents.deep.dqn import DQN_CONTINUOUS, DQN_EPISODIC
from agents.psrl_continuous import PSRL_CONTINUOUS, PSRL_CONTINUOUS_COLOSSEUM
from agents.psrl_episodic import PSRL_EPISODIC, PSRL_EPISODIC_COLOSSEUM
from agents.q_learning_continuous import Q_LEARNING_CONTINUOUS, Q_LEARNING_CONTINUOUS_COLOSSEUM
from agents.q_learning_episodic import Q_LEARNING_EPISODIC, Q_LEARNING_EPISODIC_COLOSSEUM
from agents.random_agent import RANDOM_CONTINUOUS, RANDOM_EPISODIC
from agents.ucrl2 import UCRL2, UCRL2_COLOSSEUM
from jaxmdp._checks import VARIANTS, Variant, check_variant, did_you_mean
from jaxmdp.experiment.agent_interface import Agent

AGENTS: dict[str, Agent] = {
    a.name: a
    for a in (
        RANDOM_EPISODIC,
        RANDOM_CONTINUOUS,
        Q_LEARNING_EPISODIC,
        Q_LEARNING_CONTINUOUS,
        PSRL_EPISODIC,
        PSRL_CONTINUOUS,
        UCRL2,
        DQN_EPISODIC,
        DQN_CONTINUOUS,
        BOOT_DQN_EPISODIC,
        BOOT_DQN_CONTINUOUS,
        ACTOR_CRITIC_EPISODIC,
        ACTOR_CRITIC_CONTINUOUS,
        ACTOR_CRITIC_RNN_EPISODIC,
        ACTOR_CRITIC_RNN_CONTINUOUS,
    )
}


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
    names when unknown, or when the agent has no such variant (the deep agents have only ``"paper"``)."""
    check_variant(variant)
    base, at, suffix = name.partition("@")
    if at:
        if suffix not in VARIANTS or (variant != "paper" and variant != suffix):
            raise ValueError(f"agent name {name!r}: the part after '@' must be a variant {VARIANTS} (not also another "
                             f"variant={variant!r})")
        name, variant = base, suffix
    if name not in AGENTS:
        raise ValueError(f"unknown agent {name!r}{did_you_mean(name, AGENTS, 0.5)} Registered: {', '.join(AGENTS)}")
    if variant == "paper":
        return AGENTS[name]
    if name not in COLOSSEUM_AGENTS:
        raise ValueError(f"agent {name!r} has no {variant!r} variant (reference mode); those that have one: "
                         f"{', '.join(COLOSSEUM_AGENTS)}")
    return COLOSSEUM_AGENTS[name]


__all__ = ["AGENTS", "COLOSSEUM_AGENTS", "get"]
