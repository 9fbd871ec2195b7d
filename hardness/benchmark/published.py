"""The paper's published benchmark numbers (§3.3 Table 2, App. G Tables 9-12 and App. G "Non-tabular setting"), as
data beside which the report puts ours.

Every number is the per-step normalised cumulative regret (App. E; the final ``normalized_cumulative_regret``
divided by the 500 000 steps), or the matching normalised (expected) reward, mean and standard deviation over 20
seeds, as printed (two decimals). Keys: the setting, the agent's registry name, and the MDP's label in
:mod:`hardness.benchmark.sets` (``"Family/prms_i"``). The paper numbers the MDPs of a family ``(1), (2), ...`` in the
order of the benchmark's gin scopes, so row ``(k)`` is ``prms_{k-1}``. The reference cut every run off after ten
minutes of wall clock (docs/benchmark.md §2): ``completed`` counts the seeds that reached all 500 000 steps before it.

Table 2 and App. G agree on every mean; a few standard deviations differ by 0.01 (e.g. episodic communicating
MG-Empty (1), PSRL: ``.09 ± .05`` against ``0.09 ± 0.04``); both are kept as printed. Table 2's *Average* row is the
mean and the population standard deviation (``ddof = 0``) over the 20 MDPs of the per-MDP means.

The non-tabular numbers (:data:`NONTABULAR`, :data:`NONTABULAR_AVERAGE`) are App. G's table
``tab:nt_benchmark_table_e`` (sub-tables (a) episodic communicating, (b) episodic ergodic, (c) continuous
communicating, (d) continuous ergodic): the per-step normalised regret, mean ± std over 20 seeds, of the ``bsuite``
agents ActorCritic, ActorCriticRNN, BootDQN and DQN (registry names ``actor_critic_*``, ``actor_critic_rnn_*``,
``boot_dqn_*``, ``dqn_*``), which observed each MDP through the deterministic state-information emission map
(:data:`NONTABULAR_EMISSION`) and were cut off after 40 minutes of wall clock (the paper prints no completed-seed
counts for them). Rows and the *Average* row follow Table 2's conventions above (average: mean and ``ddof = 0`` standard
deviation of the 20 per-MDP means). The paper has no other copy of these numbers: the App. G table captioned "Summary
of benchmark results for the non-tabular bsuite baselines" (``tab:benchmark_table``) holds the *tabular* agents
(PSRL, Q-learning, UCRL2), its numbers equal to Table 2's, and §3.3 Table 2 has no non-tabular columns.

The numbers are package data, one CSV per table in ``hardness/benchmark/data/`` (``table2.csv``,
``table2_average.csv``, ``appendix_g.csv``, ``nontabular.csv``, ``nontabular_average.csv``; numbers as printed, rows
in the paper's order), read once when this module is imported into the nested dictionaries below.
"""

from __future__ import annotations

import csv
from importlib import resources
from typing import NamedTuple

__all__ = [
    "AppendixRow",
    "TABLE2",
    "TABLE2_AVERAGE",
    "APPENDIX_G",
    "NONTABULAR",
    "NONTABULAR_AVERAGE",
    "NONTABULAR_EMISSION",
    "table2",
    "appendix_g",
    "nontabular",
    "regret_table",
    "regret_average",
]

#: The emission kind (:data:`jaxmdp.EMISSION_KINDS`) through which the paper's non-tabular agents observed the MDPs.
NONTABULAR_EMISSION = "state_info"


class AppendixRow(NamedTuple):
    """One (MDP, agent) row of App. G: ``(mean, std)`` of the normalised cumulative reward, normalised cumulative
    expected reward and normalised cumulative regret (per step), and the seeds (of 20) that completed."""

    reward: tuple[float, float]
    expected_reward: tuple[float, float]
    regret: tuple[float, float]
    completed: int


def table2(setting: str, agent: str, label: str) -> tuple[float, float] | None:
    """Table 2's ``(mean, std)`` of ``agent`` on the MDP ``label`` of ``setting``; ``None`` where the paper has none."""
    return TABLE2.get(setting, {}).get(agent, {}).get(label)


def appendix_g(setting: str, agent: str, label: str) -> AppendixRow | None:
    """App. G's row of ``agent`` on the MDP ``label`` of ``setting``; ``None`` where the paper has none."""
    return APPENDIX_G.get(setting, {}).get(agent, {}).get(label)


def nontabular(setting: str, agent: str, label: str) -> tuple[float, float] | None:
    """App. G's non-tabular ``(mean, std)`` of the deep ``agent`` on the MDP ``label`` of ``setting``; ``None`` where
    the paper has none."""
    return NONTABULAR.get(setting, {}).get(agent, {}).get(label)


def regret_table(setting: str, emission: str | None = None) -> dict[str, dict[str, tuple[float, float]]]:
    """The paper's per-step normalised regret ``{agent: {label: (mean, std)}}`` for a run of ``setting`` whose agents
    observed ``emission`` (a :data:`jaxmdp.EMISSION_KINDS` name, ``None`` for the states): Table 2's tabular agents,
    and the non-tabular agents when ``emission`` is the paper's (:data:`NONTABULAR_EMISSION`); the paper has no
    numbers for other emissions."""
    table = dict(TABLE2.get(setting, {}))
    if emission == NONTABULAR_EMISSION:
        table.update(NONTABULAR.get(setting, {}))
    return table


def regret_average(setting: str, agent: str) -> tuple[float, float] | None:
    """The paper's printed *Average* row ``(mean, std)`` of ``agent`` over the 20 MDPs of ``setting`` (Table 2 or the
    non-tabular table); ``None`` where the paper has none."""
    return TABLE2_AVERAGE.get(setting, {}).get(agent) or NONTABULAR_AVERAGE.get(setting, {}).get(agent)


def _rows(name: str) -> list[dict[str, str]]:
    """The rows of the package data file ``data/<name>.csv``."""
    with resources.files(__package__).joinpath("data", f"{name}.csv").open(newline="") as f:
        return list(csv.DictReader(f))


def _pair(row: dict[str, str], prefix: str = "") -> tuple[float, float]:
    return float(row[f"{prefix}mean"]), float(row[f"{prefix}std"])


def _per_label(name: str, value) -> dict:
    """``{setting: {agent: {label: value(row)}}}`` of a per-MDP table, in the file's order."""
    table: dict = {}
    for row in _rows(name):
        table.setdefault(row["setting"], {}).setdefault(row["agent"], {})[row["label"]] = value(row)
    return table


def _averages(name: str) -> dict[str, dict[str, tuple[float, float]]]:
    """``{setting: {agent: (mean, std)}}`` of an *Average* table, in the file's order."""
    table: dict = {}
    for row in _rows(name):
        table.setdefault(row["setting"], {})[row["agent"]] = _pair(row)
    return table


def _appendix_row(row: dict[str, str]) -> AppendixRow:
    return AppendixRow(_pair(row, "reward_"), _pair(row, "expected_reward_"), _pair(row, "regret_"),
                       int(row["completed"]))


#: Table 2: ``{setting: {agent: {label: (mean, std)}}}`` of the per-step normalised regret.
TABLE2: dict[str, dict[str, dict[str, tuple[float, float]]]] = _per_label("table2", _pair)
#: Table 2's *Average* rows: ``{setting: {agent: (mean, std)}}``.
TABLE2_AVERAGE: dict[str, dict[str, tuple[float, float]]] = _averages("table2_average")
#: App. G Tables 9-12: ``{setting: {agent: {label: AppendixRow}}}``.
APPENDIX_G: dict[str, dict[str, dict[str, AppendixRow]]] = _per_label("appendix_g", _appendix_row)
#: App. G's non-tabular table: ``{setting: {agent: {label: (mean, std)}}}`` of the per-step normalised regret.
NONTABULAR: dict[str, dict[str, dict[str, tuple[float, float]]]] = _per_label("nontabular", _pair)
#: The non-tabular table's *Average* rows: ``{setting: {agent: (mean, std)}}``.
NONTABULAR_AVERAGE: dict[str, dict[str, tuple[float, float]]] = _averages("nontabular_average")
