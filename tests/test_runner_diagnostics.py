"""Silent degradation made visible: UCRL2's and optimistic PSRL's count of unconverged plans and their slot-overflow
flag (``Agent.diagnostics``) are columns of the runner's records and CSV, and a run that ends with a non-zero count
warns."""

from __future__ import annotations

import csv
import warnings

import numpy as np
import pytest

import agents
import jaxmdp
from jaxmdp.experiment import runner
from jaxmdp.experiment.indicators import CSV_COLUMNS

MDP = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)
CAPPED = {
    "ucrl2": agents.AGENTS["ucrl2"].default_hparams.replace(evi_max_iter=1),
    # Average-reward planning (discount 1) with one sweep cannot meet the span rule.
    "psrl_continuous": agents.AGENTS["psrl_continuous"].default_hparams.replace(discount=1.0, plan_max_iter=1,
                                                                                max_psi=2),
}


def _read(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


# UCRL2 first: the default profile runs the first set (tests/nightly_params.txt), and UCRL2's chunk program is the
# one test_converged_planning_records_zero_and_does_not_warn compiles; continuous PSRL's own unconverged count is
# test_psrl_continuous.py's.
@pytest.mark.parametrize("name", ["ucrl2", "psrl_continuous"])
def test_an_iteration_cap_of_one_is_counted_recorded_and_warned(name, tmp_path):
    agent = agents.AGENTS[name]
    g = runner.product([MDP], [CAPPED[name]], seeds=[0, 1])
    with pytest.warns(RuntimeWarning, match=rf"{name}: plans_unconverged = \d+ over the run \(2 of 2 members\)"):
        res = runner.run(agent, g, 400, log_period=50, n_records=4, csv_path=tmp_path / "run.csv")
    assert res.diagnostic_names == ("plans_unconverged", "slots_overflowed")
    final = np.asarray(res.agent_state.plans_unconverged)
    # Every plan is unconverged: the init plan plus one per epoch start, all counted.
    assert np.all(final >= 2)
    counts, overflowed = res.values[..., -2], res.values[..., -1]
    assert np.all(np.diff(counts, axis=0) >= 0)
    np.testing.assert_array_equal(counts[-1], final)
    assert not np.any(overflowed)  # the runner's spec_of: the slots hold every next state
    header, rows = _read(tmp_path / "run.csv")
    assert header == list(runner.MEMBER_COLUMNS + CSV_COLUMNS) + ["plans_unconverged", "slots_overflowed"]
    column = np.array([int(r[-2]) for r in rows]).reshape(len(res.steps), 2)
    np.testing.assert_array_equal(column, counts)
    res.write_csv(tmp_path / "again.csv")
    again_header, again = _read(tmp_path / "again.csv")
    assert again_header == header and [r[-2:] for r in again] == [r[-2:] for r in rows]


def test_converged_planning_records_zero_and_does_not_warn():
    agent = agents.AGENTS["ucrl2"]
    g = runner.product([MDP], [agent.default_hparams], seeds=[0])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = runner.run(agent, g, 400, log_period=50, n_records=4)
    assert int(res.agent_state.plans_unconverged[0]) == 0 == res.values[..., -2:].max()
    assert not [w for w in caught if "plans_unconverged" in str(w.message)]


def test_agents_without_diagnostics_keep_their_columns(tmp_path):
    agent = agents.AGENTS["q_learning_continuous"]
    res = runner.run(agent, runner.product([MDP], [agent.default_hparams], seeds=[0]), 200, n_records=2,
                     csv_path=tmp_path / "q.csv")
    assert res.diagnostic_names == () and res.values.shape[-1] == 4
    assert _read(tmp_path / "q.csv")[0] == list(runner.MEMBER_COLUMNS + CSV_COLUMNS)
