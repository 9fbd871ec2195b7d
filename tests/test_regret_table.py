"""scripts/regret_table.py: the table's numbers are the runner's columns (mean and Student-t CI over seeds), the CSVs
agree with them, and a second invocation reuses the finished agents."""

from __future__ import annotations

import csv
import importlib.util
import math
import sys

import numpy as np
import pytest
from scipy import special, stats

from conftest import REPO

_spec = importlib.util.spec_from_file_location("regret_table", REPO / "scripts" / "regret_table.py")
regret_table = importlib.util.module_from_spec(_spec)
sys.modules["regret_table"] = regret_table  # dataclasses look their module up while the class is created
_spec.loader.exec_module(regret_table)

STEPS, SEEDS = 300, 3
ARGS = ["--steps", str(STEPS), "--seeds", str(SEEDS), "--families", "RiverSwim", "DeepSea", "--sizes", "3",
        "--agents", "q_learning_episodic", "--quiet"]


@pytest.mark.parametrize("df", [1, 2, 5, 19, 200])
def test_t_quantile_matches_scipy(df):
    for q in (0.975, 0.9):
        assert regret_table.t_quantile(q, df) == pytest.approx(stats.t.ppf(q, df), rel=1e-10)


@pytest.mark.parametrize("a, b, x", [(1.0, 0.5, 0.3), (100.0, 0.5, 0.99), (0.5, 0.5, 0.5), (2.5, 0.5, 0.1),
                                     (10.0, 0.5, 0.95), (3.0, 7.0, 0.0), (3.0, 7.0, 1.0)])
def test_betainc_matches_scipy(a, b, x):
    assert regret_table.betainc(a, b, x) == pytest.approx(special.betainc(a, b, x), rel=1e-12, abs=1e-15)


def test_mean_ci_matches_scipy():
    x = np.array([0.1, 0.4, 0.25, 0.3, 0.05])
    mean, half = regret_table.mean_ci(x)
    lo, hi = stats.t.interval(0.95, x.size - 1, loc=x.mean(), scale=stats.sem(x))
    assert mean == pytest.approx(x.mean(), abs=1e-15)
    assert half == pytest.approx((hi - lo) / 2, rel=1e-10)
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
            half = stats.t.ppf(0.975, SEEDS - 1) * x.std(ddof=1) / math.sqrt(SEEDS)
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
