"""Tabular agents as pure functions over pytrees (see the agents issue).

``AGENTS`` maps a name to its :class:`jaxmdp.agent_interface.Agent`.
"""

from agents.psrl_continuous import PSRL_CONTINUOUS
from agents.psrl_episodic import PSRL_EPISODIC
from agents.ucrl2 import UCRL2

AGENTS = {
    PSRL_EPISODIC.name: PSRL_EPISODIC,
    PSRL_CONTINUOUS.name: PSRL_CONTINUOUS,
    UCRL2.name: UCRL2,
}

__all__ = ["AGENTS"]
