"""What a lockstep run produces: records of the running sums and the reference's CSV columns.

A record holds, for every member, the four running sums the runner accumulates
(:data:`jaxmdp.experiment.indicators.AGENT_COLUMNS`); every other column of the reference's CSV (docs/benchmark.md §2)
follows from them, the step count and the member's :class:`~jaxmdp.experiment.indicators.IndicatorConstants`.
"""

from __future__ import annotations

import csv
import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np

from jaxmdp.experiment.indicators import AGENT_COLUMNS, CSV_COLUMNS, baseline_columns, normalized_reward
from jaxmdp.experiment.members import Grid

__all__ = [
    "format_row",
    "RunResult",
    "record_steps",
    "MEMBER_COLUMNS",
    "csv_rows",
    "append_rows",
    "truncate_csv",
]

#: Columns that identify a member in the CSV, before the reference's columns.
MEMBER_COLUMNS = ("member", "mdp", "hparams", "seed")


def record_steps(n_steps: int, log_period: int = 100, n_records: int = 100) -> tuple[int, np.ndarray]:
    """The record period and the step counts at which records are made.

    Records are made every ``record_period`` steps, a multiple of ``log_period`` chosen so that there are at most
    ``n_records`` of them, and after the last step.
    """
    n_logs = -(-n_steps // log_period)
    record_period = log_period * -(-n_logs // n_records)
    steps = np.arange(record_period, n_steps + 1, record_period)
    if steps.size == 0 or steps[-1] != n_steps:
        steps = np.append(steps, n_steps)
    return record_period, steps


@dataclasses.dataclass
class RunResult:
    """Records of a run.

    Attributes:
      steps: ``[R]`` step counts of the records.
      values: ``[R, B, 4 + D]`` running sums (:data:`jaxmdp.experiment.indicators.AGENT_COLUMNS`) at each record,
        then the agent's ``D`` diagnostics (``diagnostic_names``).
      constants: the members' :class:`~jaxmdp.experiment.indicators.IndicatorConstants` (numpy, leading axis ``B``).
      grid: the members.
      agent: the agent's name.
      compile_s: seconds spent compiling (initialisation and loop programs) and computing the indicator constants.
      run_s: seconds spent running the loop (compilation excluded), over every session of a resumed run.
      n_steps, log_period, record_period, variant: the settings.
      agent_state: the members' final agent states (numpy, leading axis ``B``).
      visits: ``[B, S]`` counts of the states each member acted in, when the run was asked to record them
        (``run(..., record_visits=True)``), else None.
      diagnostic_names: the agent's diagnostics (``Agent.diagnostics``), the last columns of ``values`` and the CSV.
      stopped_at: ``[B]`` the step after which each member stopped learning (0: it never did), for a run with the
        reference's convergence stop (``run(..., stop_when_converged=True)``), else None.
    """

    steps: np.ndarray
    values: np.ndarray
    constants: Any
    grid: Grid
    agent: str
    compile_s: float
    run_s: float
    n_steps: int
    log_period: int
    record_period: int
    variant: str
    agent_state: Any = None
    visits: np.ndarray | None = None
    diagnostic_names: tuple[str, ...] = ()
    stopped_at: np.ndarray | None = None

    @property
    def agent_steps_per_second(self) -> float:
        """Interaction steps per second summed over members (the lockstep throughput)."""
        done = int(self.steps[-1]) if self.steps.size else 0
        return done * self.grid.n_members / self.run_s if self.run_s > 0 else float("nan")

    def column(self, name: str) -> np.ndarray:
        """One CSV column as ``[R, B]`` (float64)."""
        return _columns(self.steps, self.values, self.constants)[name]

    def rows(self) -> list[list[Any]]:
        """All CSV rows (member columns, then the reference's columns), record-major."""
        return csv_rows(self.grid, self.steps, self.values, self.constants, self._steps_per_member_second())

    def _steps_per_member_second(self) -> np.ndarray:
        return np.full(self.steps.shape, int(self.steps[-1]) / self.run_s if self.run_s > 0 else np.nan)

    def write_csv(self, path: str | os.PathLike) -> None:
        """Write every record to one CSV (``member, mdp, hparams, seed`` and the reference's columns)."""
        with open(path, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(MEMBER_COLUMNS + CSV_COLUMNS + self.diagnostic_names)
            writer.writerows(format_row(r) for r in self.rows())


def _columns(steps, values, constants) -> dict[str, np.ndarray]:
    steps = np.asarray(steps, np.float64)[:, None]
    v = np.asarray(values, np.float64)
    opt, wst, rnd = (np.asarray(x, np.float64)[None, :] for x in (constants.optimal, constants.worst, constants.random))
    cols = {name: v[..., i] for i, name in enumerate(AGENT_COLUMNS)}
    cols["steps"] = np.broadcast_to(steps, v.shape[:2])
    cols["normalized_cumulative_reward"] = normalized_reward(cols["cumulative_reward"], steps, opt, wst)
    cols["normalized_cumulative_expected_reward"] = normalized_reward(cols["cumulative_expected_reward"], steps, opt, wst)
    cols.update(baseline_columns(steps, opt, wst, rnd))
    return cols


def csv_rows(g: Grid, steps, values, constants, per_second) -> list[list[Any]]:
    """CSV rows (member columns, the reference's, then the agent's diagnostics) of records ``steps``/``values``,
    record-major."""
    cols = _columns(steps, values, constants)
    out = []
    for r in range(len(steps)):
        for b in range(g.n_members):
            out.append(
                [b, g.mdp_labels[g.mdp_index[b]], int(g.hparams_index[b]), int(g.seeds[b]), int(steps[r])]
                + [cols[name][r, b] for name in CSV_COLUMNS[1:-1]]
                + [per_second[r]]
                + [int(x) for x in np.asarray(values)[r, b, len(AGENT_COLUMNS):]]
            )
    return out


def format_row(row: list[Any]) -> list[str]:
    """CSV fields of a row: integers as integers, floats with 9 significant digits (float32 round-trips)."""
    out = []
    for x in row:
        if isinstance(x, str):
            out.append(x)
        elif isinstance(x, (int, np.integer)):
            out.append(str(int(x)))
        else:
            out.append(f"{float(x):.9g}")
    return out


def append_rows(path: Path, rows: list[list[Any]]) -> None:
    """Append rows to a CSV file."""
    with open(path, "a", newline="") as f:
        csv.writer(f).writerows(format_row(r) for r in rows)


def truncate_csv(path: Path, t: int, diagnostic_names: tuple[str, ...] = ()) -> None:
    """Drop rows written after the checkpoint at step ``t`` (a crash between writing rows and checkpointing)."""
    header = list(MEMBER_COLUMNS + CSV_COLUMNS + tuple(diagnostic_names))
    rows = []
    if path.exists():
        with open(path, newline="") as f:
            reader = csv.reader(f)
            if next(reader, None) == header:
                col = header.index("steps")
                rows = [r for r in reader if len(r) == len(header) and int(r[col]) <= t]
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
