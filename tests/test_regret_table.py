"""hardness.analysis.regret_table (run by ``jaxmdp-regret-table``): the table's numbers are the runner's columns (mean
and Student-t CI over seeds), the CSVs agree with them, and a second invocation reuses the finished agents."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from hardness.analysis import regret_table

STEPS, SEEDS = 300, 3
ARGS = ["--steps", str(STEPS), "--seeds", str(SEEDS), "--families", "RiverSwim", "DeepSea", "--sizes", "3",
        "--agents", "q_learning_episodic", "--quiet"]


def t_975(df: int) -> float:
    """The 0.975-quantile of Student's t in closed form, for 1 and 2 degrees of freedom (CDFs
    ``1/2 + atan(t)/pi`` and ``1/2 + t / (2 sqrt(2 + t^2))``)."""
    p = 0.975
    return {1: math.tan(math.pi * (p - 0.5)), 2: (2 * p - 1) / math.sqrt(2 * p * (1 - p))}[df]


def test_mean_ci_is_the_student_t_interval():
    x = np.array([0.1, 0.4, 0.25])
    mean, half = regret_table.mean_ci(x)
    s = math.sqrt(sum((v - 0.25) ** 2 for v in x) / 2)  # the sample standard deviation (mean 0.25)
    assert mean == pytest.approx(0.25, abs=1e-15)
    assert half == pytest.approx(t_975(2) * s / math.sqrt(3), rel=1e-12)
    assert regret_table.mean_ci(np.array([0.2, 0.6]))[1] == pytest.approx(t_975(1) * 0.2, rel=1e-12)
    assert math.isnan(regret_table.mean_ci(np.array([0.3]))[1])


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    out = tmp_path_factory.mktemp("regret_table")
    return out, regret_table.main(ARGS + ["--out", str(out)])


def test_table_equals_runner_columns(table):
    out, res = table
    result = res["results"]["q_learning_episodic"]
    g = result.grid
    assert g.n_members == 2 * SEEDS and int(result.steps[-1]) == STEPS
    norm = result.column("normalized_cumulative_regret")[-1] / STEPS
    raw = result.column("cumulative_regret")[-1]
    rnd = result.column("random_normalized_cumulative_regret")[-1] / STEPS
    rows = {r["mdp"]: r for r in res["rows"]}
    assert list(rows) == ["RiverSwim-3", "DeepSea-3"]
    for i, name in enumerate(rows):
        members = g.mdp_index == i
        assert sorted(g.seeds[members].tolist()) == list(range(SEEDS))
        r = rows[name]
        for column, x in (("normalized_regret_per_step", norm[members]), ("cumulative_regret", raw[members])):
            assert r[f"{column}_mean"] == pytest.approx(x.mean(), rel=1e-12, abs=1e-15)
            half = t_975(SEEDS - 1) * x.std(ddof=1) / math.sqrt(SEEDS)
            assert r[f"{column}_ci95"] == pytest.approx(half, rel=1e-10, abs=1e-15)
        assert r["random_baseline_normalized_regret_per_step"] == pytest.approx(rnd[members][0], rel=1e-12)
        assert r["n_seeds"] == SEEDS and r["n_steps"] == STEPS
    # The learning agent must differ from the baseline somewhere, or the comparison above proves little.
    assert not np.allclose(norm, rnd)


def test_csv_files_agree_with_table(table):
    out, res = table
    with (out / "regret_table.csv").open() as f:
        written = list(csv.DictReader(f))
    assert len(written) == len(res["rows"])
    for w, r in zip(written, res["rows"]):
        assert w["mdp"] == r["mdp"] and w["agent"] == r["agent"]
        assert float(w["normalized_regret_per_step_mean"]) == pytest.approx(r["normalized_regret_per_step_mean"],
                                                                            rel=1e-8)
    # The runner's own CSV (its last record) holds the same per-member values.
    (runner_csv,) = (out / "runs").glob("q_learning_episodic-*.csv")
    with runner_csv.open() as f:
        last = [rec for rec in csv.DictReader(f) if int(rec["steps"]) == STEPS]
    members = res["runs"][0].members
    assert len(last) == len(members)
    for rec, m in zip(sorted(last, key=lambda x: int(x["member"])), members):
        assert int(rec["seed"]) == m["seed"]
        assert float(rec["normalized_cumulative_regret"]) / STEPS == pytest.approx(m["normalized_regret_per_step"],
                                                                                    rel=1e-7)
        assert float(rec["cumulative_regret"]) == pytest.approx(m["cumulative_regret"], rel=1e-7)
    assert "| q_learning_episodic |" in (out / "regret_table.md").read_text()


def test_second_invocation_reuses_finished_agents(table):
    out, res = table
    again = regret_table.main(ARGS + ["--out", str(out)])
    assert again["results"] == {}  # nothing ran
    assert again["rows"] == res["rows"]  # the JSON summary round-trips every float exactly
