"""The result tables of a benchmark run (:mod:`hardness.benchmark.run`): ``members.csv`` and ``batches.csv``, rewritten
from the finished batches' records in ``runs/`` in the plan's order, each written atomically (a crash never leaves
half a file; processes sharing a folder write them under its lock,
:func:`hardness.benchmark.plans.write_folder_tables`)."""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hardness.benchmark import sets
from jaxmdp.experiment import records

if TYPE_CHECKING:
    from hardness.benchmark.plans import Batch

__all__ = ["MEMBER_FIELDS", "BATCH_FIELDS", "write_tables"]

#: Columns of ``members.csv``.
MEMBER_FIELDS = (
    "set", "mdp", "family", "agent", "seed", "steps", "cumulative_regret", "normalized_cumulative_regret",
    "normalized_regret_per_step", "normalized_cumulative_reward", "normalized_cumulative_expected_reward",
    "random_normalized_regret_per_step", "batch",
)
#: Columns of ``batches.csv``. ``compile_s``: seconds compiling the batch's programs (in the call that finished it);
#: ``run_s``: seconds of its lockstep loop, over every call that ran a part of it; ``member_steps_per_s``: steps of one
#: member per second of the lockstep loop (``n_steps / run_s``); ``agent_steps_per_s``: summed over the batch's
#: members; ``host``, ``pid``: the process that finished it (empty for a batch finished before they were recorded).
BATCH_FIELDS = (
    "batch", "set", "agent", "members", "mdps", "max_states", "compile_s", "run_s", "member_steps_per_s",
    "agent_steps_per_s", "host", "pid",
)


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _finished(run_dir: Path, batch: Batch) -> dict | None:
    path = run_dir / f"{batch.id}.json"
    if path.exists():
        saved = json.loads(path.read_text())
        if saved.get("key") == batch.key:
            return saved
    return None


def _write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(records.format_row(list(r)) for r in rows)
    os.replace(tmp, path)


def write_tables(out: Path, settings: dict, batches: Sequence[Batch]) -> int:
    """Rewrite ``members.csv`` and ``batches.csv`` from the finished batches, in the plan's order (sets, MDPs of a
    set in their order, agents, seeds); returns the number of member rows."""
    run_dir = out / "runs"
    order = {s: {i.label: k for k, i in enumerate(sets.instances(s))} for s in settings["sets"]}
    rows, brows = [], []
    for batch in batches:
        saved = _finished(run_dir, batch)
        if saved is None:
            continue
        agents = settings["agents"][batch.set_name]
        for m in saved["members"]:
            sort = (settings["sets"].index(batch.set_name), order[batch.set_name][m["mdp"]],
                    agents.index(batch.agent), m["seed"])
            rows.append((sort, [batch.set_name, m["mdp"], m["family"], batch.agent, m["seed"], m["steps"]]
                         + [m[f] for f in MEMBER_FIELDS[6:-1]] + [batch.id]))
        run_s = saved["run_s"]
        brows.append([batch.id, batch.set_name, batch.agent, saved["n_members"], saved["n_mdps"], saved["max_states"],
                      round(saved["compile_s"], 2), round(run_s, 2), saved["n_steps"] / run_s,
                      saved["n_steps"] * saved["n_members"] / run_s, saved.get("host", ""), saved.get("pid", "")])
    rows.sort(key=lambda r: r[0])
    _write_csv(out / "members.csv", MEMBER_FIELDS, [r for _, r in rows])
    _write_csv(out / "batches.csv", BATCH_FIELDS, brows)
    return len(rows)
