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

from hardness.benchmark import baselines, published, sets

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

_REFERENCE_MODE = "Q-learning, reference mode"
#: The reference-mode column's folders per setting kind: the run and, in square brackets, the reference's loop.
_REFERENCE_FOLDERS = {
    "continuous": ("benchmark_continuous_full_2seeds_reference_ql", "benchmark_continuous_full_2seeds_reference_loop"),
    "episodic": ("benchmark_episodic_full_20seeds_reference_ql", "benchmark_episodic_full_20seeds_reference_loop"),
}


def _committed_folder(setting: str, agent: str) -> str:
    """The folder of the committed run at the paper's protocol (500 000 steps) that holds ``agent`` on ``setting``
    (:data:`hardness.benchmark.baselines.COMMITTED_RUNS`): Table 2's tuned cells are the committed baseline."""
    runs = [r.folder for r in baselines.COMMITTED_RUNS
            if r.n_steps == 500_000 and setting in r.sets and agent in r.agents]
    assert len(runs) == 1, (setting, agent, runs)
    return runs[0]


#: The folder of each (setting, column) with a cell; the reference-mode column has two.
SOURCES = {
    (s, column): (_REFERENCE_FOLDERS[s.split()[0]] if column == _REFERENCE_MODE
                  else _committed_folder(s, agents[s.startswith("continuous")]))
    for s in sets.SETTINGS for column, agents in COLUMNS.items() if agents[s.startswith("continuous")] is not None
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


def test_the_page_names_every_folder_it_draws_on():
    """Each cell's folder is in the page's "Where each cell comes from" table, as ``folder/``."""
    text = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    table = text.split("Where each cell comes from", 1)[1].split("\n\n", 2)[1]
    folders = {f for v in SOURCES.values() for f in ((v,) if isinstance(v, str) else v)}
    assert {f for f in folders if f"`{f}/`" not in table} == set()
