"""Where the benchmark's hyperparameters come from: the reference's cached values, a tuned file, and search candidates.

* ``"reference"``: the agents' ``default_hparams``, which are the reference's cached values (agents.md). They were
  tuned by the reference for its own update rules, several of which differ from ours (the ``[quirk]`` entries of
  agents.md), so they are not "tuned" for this code; reference mode (``variant="colosseum"`` of :func:`hparams_for`,
  ``--agent-variant colosseum``) runs them with the rules they were tuned for.
* ``"tuned"``: :data:`TUNED_FILE`, the shipped file (package data, read only: ``jaxmdp-benchmark tune`` writes into
  its output folder unless told this path, :mod:`hardness.benchmark.search`), each entry with its provenance (budget,
  seeds, commit, date); any other path: a file of the same format (``tune``'s output, which starts as a copy of the
  shipped file, so that it also holds the shipped agents' values).
* :func:`reference_candidates`: random-search candidates drawn as the reference draws them (agents.md §8): sample
  ``i`` of a search with seed ``sigma`` uses a generator seeded with ``sigma + i`` (here a private
  ``numpy.random.RandomState``, the same stream as the reference's seeded global one), draws every field of the
  agent's search space in order as ``uniform(low, high)`` and rounds it to 4 decimals.

Agents without a search space (the random agents) have no tunable hyperparameters: every source gives their
defaults. The deep agents have search spaces but the reference ships no tuned values for them (agents.md §7): unless
the shipped file holds some, ``"tuned"`` gives their defaults too (bsuite's own, as ``"reference"``), and so it does
for an agent added with :func:`agents.register` (tune it and pass the file written by ``tune`` instead).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import agents as agent_registry
from agents import psrl_continuous
from agents.search_spaces import SEARCH_SPACES, search_space
from jaxmdp._checks import Variant
from jaxmdp.agent_interface import Agent
from jaxmdp.mdp import MDP

__all__ = [
    "TUNED_FILE",
    "reference_candidates",
    "with_values",
    "load_tuned",
    "hparams_for",
    "fit_static_sizes",
    "source_of",
]

#: The shipped tuned hyperparameters (written by ``jaxmdp-benchmark tune``).
TUNED_FILE = Path(__file__).with_name("tuned_hparams.json")


def reference_candidates(
    agent: Agent | str, n: int, seed: int = 42, *, space: Mapping[str, tuple[float, float]] | None = None
) -> list[dict[str, float]]:
    """``n`` candidate value sets of the agent's search space (or ``space``), drawn as the reference draws them
    (module docstring): candidate ``i`` is ``{f: round(U(low_f, high_f), 4)}`` from ``RandomState(seed + i)``."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer; got {n!r}")
    space = search_space(agent) if space is None else space
    out = []
    for i in range(int(n)):
        rng = np.random.RandomState(seed + i)
        out.append({f: round(float(rng.uniform(low, high)), 4) for f, (low, high) in space.items()})
    return out


def with_values(agent: Agent, values: Mapping[str, float]) -> Any:
    """The agent's default hyperparameters with ``values`` replaced (``ValueError`` for unknown fields or values
    outside their domain)."""
    default = agent.default_hparams
    unknown = sorted(set(values) - {f for f in getattr(default, "__dataclass_fields__", {})})
    if unknown:
        raise ValueError(f"agent {agent.name!r} has no hyperparameters {unknown}")
    hp = default.replace(**{k: float(v) for k, v in values.items()}) if values else default
    agent.check_hparams(hp)
    return hp


def load_tuned(path: str | os.PathLike = TUNED_FILE) -> dict[str, dict]:
    """The ``agents`` mapping of a tuned file (agent name -> ``{"values": ..., provenance}``)."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"hparams file {path} does not exist; write one with jaxmdp-benchmark tune")
    data = json.loads(path.read_text())
    if not isinstance(data, dict) or not isinstance(data.get("agents"), dict):
        raise ValueError(f"hparams file {path} must hold a JSON object with an 'agents' mapping")
    return data["agents"]


def hparams_for(name: str, source: str | os.PathLike = "tuned", variant: Variant = "paper") -> Any:
    """The hyperparameters of agent ``name`` from ``source``: ``"reference"``, ``"tuned"`` or a file path (module
    docstring). ``ValueError`` if the file has no values for a tunable agent.

    ``variant="colosseum"`` starts from the reference-mode agent's defaults (:func:`agents.get`), which carry the
    reference's fixed settings (e.g. Q-learning continuous's ``delta = 0.95``); the searched values are the same."""
    agent = agent_registry.get(name, variant)
    if str(source) == "reference" or name not in SEARCH_SPACES:
        return agent.default_hparams
    path = TUNED_FILE if str(source) == "tuned" else Path(source)
    tuned = load_tuned(path)
    if name not in tuned and str(source) == "tuned" and (agent.observation == "emission"
                                                         or name not in agent_registry.SHIPPED):
        return agent.default_hparams  # deep and registered agents: no tuned values shipped (module docstring)
    if name not in tuned:
        raise ValueError(
            f"hparams file {path} has no values for {name!r} (it has {sorted(tuned)}); tune it with "
            f"jaxmdp-benchmark tune --agents {name}, or use --hparams reference"
        )
    return with_values(agent, tuned[name]["values"])


def source_of(name: str, source: str | os.PathLike = "tuned") -> str:
    """Where :func:`hparams_for` takes the hyperparameters of ``name`` from, in words (for a report)."""
    if str(source) == "reference" or name not in SEARCH_SPACES:
        return "its defaults" if name not in agent_registry.SHIPPED else "the reference's cached values"
    path = TUNED_FILE if str(source) == "tuned" else Path(source)
    if str(source) == "tuned" and name not in load_tuned(path):
        return "its defaults (not in the shipped tuned file)"
    return "the shipped tuned file" if str(source) == "tuned" else f"the tuned file {path}"


def fit_static_sizes(name: str, hparams: Sequence[Any], mdps: Sequence[MDP]) -> list[Any]:
    """``hparams`` with static buffer sizes fitted to ``mdps``: PSRL continuous's candidate buffer ``max_psi`` set to
    the largest ``psi`` any of them needs (its docstring's advice: results do not change while ``max_psi >= psi``;
    memory and the planner's action count shrink). Other agents are returned unchanged."""
    if name != psrl_continuous.PSRL_CONTINUOUS.name:
        return list(hparams)
    sizes = {(int(np.sum(m.state_mask)), int(np.sum(m.action_mask))) for m in mdps}
    need = max(psrl_continuous.psi(hp, S, A) for hp in hparams for S, A in sizes)
    return [hp.replace(max_psi=min(hp.max_psi, need)) for hp in hparams]
