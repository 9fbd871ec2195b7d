"""Agents as pure functions over pytrees (paper §3.3; docs/agents.md): the tabular agents and the deep agents of
:mod:`agents.deep` (which observe a BlockMDP's emissions).

``AGENTS`` maps each agent's name to its :class:`jaxmdp.experiment.agent_interface.Agent`; :func:`get` looks one up.
"""

from __future__ import annotations

import difflib

from agents.deep.actor_critic import ACTOR_CRITIC_CONTINUOUS, ACTOR_CRITIC_EPISODIC
from agents.deep.actor_critic_rnn import ACTOR_CRITIC_RNN_CONTINUOUS, ACTOR_CRITIC_RNN_EPISODIC
from agents.deep.boot_dqn import BOOT_DQN_CONTINUOUS, BOOT_DQN_EPISODIC
from agents.deep.dqn import DQN_CONTINUOUS, DQN_EPISODIC
from agents.psrl_continuous import PSRL_CONTINUOUS
from agents.psrl_episodic import PSRL_EPISODIC
from agents.q_learning_continuous import Q_LEARNING_CONTINUOUS
from agents.q_learning_episodic import Q_LEARNING_EPISODIC
from agents.random_agent import RANDOM_CONTINUOUS, RANDOM_EPISODIC
from agents.ucrl2 import UCRL2
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


def get(name: str) -> Agent:
    """The registered agent ``name``; ``ValueError`` with the closest names when unknown."""
    if name not in AGENTS:
        close = difflib.get_close_matches(name, list(AGENTS), n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        raise ValueError(f"unknown agent {name!r}{hint} Registered: {', '.join(AGENTS)}")
    return AGENTS[name]


__all__ = ["AGENTS", "get"]
