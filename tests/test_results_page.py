"""docs/results.md's Table 2 recomputes from the committed run folders it names (a few CSV reads, no JAX).

The page promises that every number on it recomputes from a committed folder under ``docs/tables/``; the Table 2
cells are edited by hand when a run lands, so each is checked here against its folder's ``members.csv``: the average
over the setting's 20 MDPs of the per-step normalised regret (final ``normalized_cumulative_regret / steps``, the
mean over seeds), to the page's three decimals, with the number of seeds in brackets, and the paper's column against
the package's copy of the paper's Table 2 averages.
"""

from __future__ import annotations

import csv
import re
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from hardness.benchmark import published, sets

ROOT = Path(__file__).resolve().parent.parent
TABLES = ROOT / "docs" / "tables"

#: Table 2's columns: (agent of an episodic setting, of a continuous one).
COLUMNS = {
    "UCRL2": (None, "ucrl2"),
    "PSRL": ("psrl_episodic", "psrl_continuous"),
    "Q-learning": ("q_learning_episodic", "q_learning_continuous"),
    "Q-learning, reference mode": ("q_learning_episodic", "q_learning_continuous"),
    "random": ("random_episodic", "random_continuous"),
}

#: The folder of each (setting, column), as the page's "Where each cell comes from" table says: one folder per
#: setting kind for UCRL2, Q-learning and the random agent; the reference-mode column has a second folder, the
#: reference's loop, in square brackets; PSRL's folder per setting.
_BY_KIND = {
    "continuous": {"UCRL2": "benchmark_continuous_full_20seeds", "Q-learning": "benchmark_continuous_full_20seeds",
                   "random": "benchmark_continuous_full_20seeds",
                   "Q-learning, reference mode": ("benchmark_continuous_full_2seeds_reference_ql",
                                                  "benchmark_continuous_full_2seeds_reference_loop")},
    "episodic": {"Q-learning": "benchmark_episodic_full_20seeds_ql_random",
                 "random": "benchmark_episodic_full_20seeds_ql_random",
                 "Q-learning, reference mode": ("benchmark_episodic_full_20seeds_reference_ql",
                                                "benchmark_episodic_full_20seeds_reference_loop")},
}
_PSRL = {
    "continuous ergodic": "benchmark_tabular_20seeds",
    "continuous communicating": "benchmark_continuous_communicating_psrl_full_2seeds",
    "episodic ergodic": "benchmark_tabular_20seeds",
    "episodic communicating": "benchmark_episodic_full_2seeds",
}
SOURCES = {
    **{(s, column): folder for s in sets.SETTINGS for column, folder in _BY_KIND[s.split()[0]].items()},
    **{(s, "PSRL"): folder for s, folder in _PSRL.items()},
}


def _table2() -> dict[tuple[str, str], str]:
    """``{(setting, column): cell text}`` of the page's Table 2."""
    text = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    section = text.split("## Table 2", 1)[1]
    lines = [ln for ln in section.splitlines() if ln.startswith("|")]
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    assert header == ["setting", *COLUMNS], header
    cells = {}
    for line in lines[2:]:
        row = [c.strip() for c in line.strip("|").split("|")]
        if row[0] not in sets.SETTINGS:
            break
        cells.update({(row[0], col): cell for col, cell in zip(header[1:], row[1:])})
    assert {s for s, _ in cells} == set(sets.SETTINGS)
    return cells


def _score(folder: str, setting: str, agent: str) -> tuple[float, int]:
    """The average over the setting's MDPs of the mean per-step regret over seeds, and the number of seeds."""
    regret: dict[str, list[float]] = defaultdict(list)
    with (TABLES / folder / "members.csv").open(newline="") as f:
        for r in csv.DictReader(f):
            if r["set"] == setting and r["agent"] == agent:
                regret[r["mdp"]].append(float(r["normalized_cumulative_regret"]) / float(r["steps"]))
    assert sorted(regret) == sorted(i.label for i in sets.instances(setting)), (folder, setting, agent)
    seeds = {len(v) for v in regret.values()}
    assert len(seeds) == 1, (folder, setting, agent, seeds)
    return float(np.mean([np.mean(v) for v in regret.values()])), seeds.pop()


@pytest.mark.parametrize("key", sorted(SOURCES), ids=lambda k: f"{k[0]}, {k[1]}")
def test_a_table2_cell_is_its_folder_s_average(key):
    if not TABLES.exists():
        pytest.skip("needs the repository's docs/tables")
    setting, column = key
    cell = _table2()[key]
    agent = COLUMNS[column][setting.startswith("continuous")]
    ours, paper = cell.split(" / ") if " / " in cell else (cell, None)
    folders = SOURCES[key]
    if isinstance(folders, str):
        score, n = _score(folders, setting, agent)
        assert ours == f"{score:.3f} ({n})"
    else:
        (score, n), (loop, n_loop) = (_score(f, setting, agent) for f in folders)
        assert n == n_loop and ours == f"{score:.3f} [{loop:.3f}] ({n})"
    printed = published.regret_average(setting, agent)
    assert (paper is None) == (printed is None)
    if printed is not None:
        assert paper == f"{printed[0]:.2f}"


def test_every_cell_has_a_source_or_none():
    """UCRL2 has no episodic cells; every other cell is checked above."""
    cells = _table2()
    episodic = {s for s in sets.SETTINGS if s.startswith("episodic")}
    assert {k for k, v in cells.items() if v == "—"} == {(s, "UCRL2") for s in episodic}
    assert {k for k, v in cells.items() if v != "—"} == set(SOURCES)
