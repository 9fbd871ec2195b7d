"""hardness.analysis.measure_evaluation and its command line (hardness.cli.measure_evaluation): rank correlations
against hand-worked examples, the bootstrap over seeds, the extra measures rebuilt from a sweep's settings, and the
command's outputs."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import hardness
import jaxmdp
from hardness.analysis import measure_evaluation as me
from hardness.analysis import scenarios, sweep_cli



def test_rankdata_mid_ranks():
    np.testing.assert_array_equal(me.rankdata([10, 20, 20, 5]), [2, 3.5, 3.5, 1])
    np.testing.assert_array_equal(me.rankdata([3, 3, 3]), [2, 2, 2])


def test_spearman_hand_worked():
    # y's ranks [1, 2, 3.5, 5, 3.5]; centred x ranks [-2..2], centred y ranks [-2, -1, .5, 2, .5]:
    # rho = 8 / sqrt(10 * 9.5).
    assert math.isclose(me.spearman([1, 2, 3, 4, 5], [5, 6, 7, 8, 7]), 8 / math.sqrt(95), rel_tol=1e-12)
    assert me.spearman([1, 2, 3], [30, 20, 10]) == -1.0
    assert me.spearman([1, 2, 3], [1, 4, 9]) == 1.0  # any increasing map
    assert math.isnan(me.spearman([1, 1, 1], [1, 2, 3]))


def test_kendall_tau_b_hand_worked():
    # 10 pairs: 8 concordant, 1 discordant ((8, 7)), 1 tied in y ((7, 7)): tau_b = 7 / sqrt(10 * 9).
    assert math.isclose(me.kendall_tau_b([1, 2, 3, 4, 5], [5, 6, 7, 8, 7]), 7 / math.sqrt(90), rel_tol=1e-12)
    # Ties in both: 1 concordant, 1 discordant, 2 tied in x, 2 tied in y: 0 / sqrt(4 * 4).
    assert me.kendall_tau_b([1, 1, 2, 2], [1, 2, 1, 2]) == 0.0
    # x = [1, 2, 3, 4], y = [1, 3, 2, 4]: 5 concordant, 1 discordant, no ties: 4 / 6.
    assert math.isclose(me.kendall_tau_b([1, 2, 3, 4], [1, 3, 2, 4]), 4 / 6, rel_tol=1e-12)
    assert me.kendall_tau_b([3, 2, 1], [1, 2, 3]) == -1.0
    assert math.isnan(me.kendall_tau_b([2, 2], [1, 2]))


def test_rank_correlations_match_scipy_on_tied_random_data():
    # Independent computation: scipy.stats (rankdata 'average', spearmanr, kendalltau variant 'b') on small integer
    # samples, so that most draws hold ties in x, in y and in both.
    stats = pytest.importorskip("scipy.stats")
    rng = np.random.default_rng(7)
    for n in (2, 3, 5, 8, 13, 40):
        for _ in range(20):
            x, y = rng.integers(0, 4, n).astype(float), rng.integers(0, 3, n).astype(float)
            np.testing.assert_array_equal(me.rankdata(x), stats.rankdata(x))
            if np.ptp(x) == 0 or np.ptp(y) == 0:
                assert math.isnan(me.spearman(x, y)) and math.isnan(me.kendall_tau_b(x, y))
                continue
            assert math.isclose(me.spearman(x, y), stats.spearmanr(x, y).statistic, rel_tol=1e-12, abs_tol=1e-12)
            assert math.isclose(me.kendall_tau_b(x, y), stats.kendalltau(x, y, variant="b").statistic,
                                rel_tol=1e-12, abs_tol=1e-12)


def _rows(rng, n_seeds=4, n_values=5):
    rows = []
    for s in range(n_seeds):
        for v in range(n_values):
            regret = v + 0.1 * s
            rows.append(dict(seed=s, value=v, agent_normalized_cumulative_regret=regret, good=2.0 * regret + 1,
                             bad=-regret, noise=float(rng.random()), some_inf=np.inf if v == 0 else regret))
    return rows


def test_correlations_and_bootstrap_over_seeds():
    rows = _rows(np.random.default_rng(0))
    res = {c.measure: c for c in me.correlations(rows, ["good", "bad", "noise", "some_inf"], n_boot=200)}
    assert res["good"].spearman == res["good"].kendall == 1.0
    assert res["good"].spearman_ci == (1.0, 1.0) and res["good"].kendall_ci == (1.0, 1.0)
    assert res["bad"].kendall == -1.0 and res["bad"].kendall_ci == (-1.0, -1.0)
    lo, hi = res["noise"].spearman_ci
    assert lo <= res["noise"].spearman <= hi and lo < hi
    assert res["some_inf"].n_rows == 16 and res["some_inf"].spearman == 1.0  # infinite rows left out
    again = me.correlations(rows, ["noise"], n_boot=200)[0]
    assert again.spearman_ci == res["noise"].spearman_ci  # same seed, same intervals
    with pytest.raises(ValueError, match="lack the columns"):
        me.correlations(rows, ["nope"])


def test_extra_measures_rebuild_the_sweep_mdps():
    spec = scenarios.scenario_spec(1, "RiverSwim", episodic=False, seeds=[0, 1], values=[0.0, 0.2],
                                   params=dict(size=5))
    config = sweep_cli.config_of(spec)
    rows = [dict(seed=s, value=v) for s in (1, 0) for v in (0.2, 0.0)]
    extra = me.extra_measures(rows, config)
    for k, row in enumerate(rows):
        m = jaxmdp.make("RiverSwim", episodic=False, seed=row["seed"], **{**dict(spec.params), "p_rand": row["value"]})
        uniform = np.full((m.n_states, m.n_actions), 0.5, np.float32)
        assert extra["mixing_time"][k] == float(hardness.mixing_time(m, lazy=True).value)
        np.testing.assert_allclose(extra["distribution_mismatch"][k],
                                   float(hardness.distribution_mismatch(m, None, uniform).value), rtol=1e-4)


def test_script_writes_table_csv_and_figure(tmp_path):
    spec = scenarios.scenario_spec(1, "RiverSwim", episodic=False, seeds=[0, 1, 2], values=[0.0, 0.1, 0.3],
                                   params=dict(size=5))
    rng = np.random.default_rng(1)
    raw = {m: rng.random((3, 3)) for m in scenarios.MEASURES}
    raw.update({f"{m}_converged": np.ones((3, 3), bool) for m in scenarios.MEASURES})
    raw.update(n_states=np.full((3, 3), 5), agent="ucrl2", agent_cumulative_regret=rng.random((3, 3)),
               agent_normalized_cumulative_regret=rng.random((3, 3)))
    table = tmp_path / "scenario1.csv"
    sweep_cli.write_table(table, sweep_cli.rows_from_raw(spec, [0, 1, 2], raw))
    table.with_suffix(".json").write_text(json.dumps(sweep_cli.config_of(spec)))
    from hardness.cli import measure_evaluation as script

    assert script.main([str(table), "--out", str(tmp_path / "out"), "--n-boot", "50", "--no-compile-cache"]) == 0
    md = (tmp_path / "out" / "measure_evaluation.md").read_text()
    for m in (*scenarios.MEASURES, *me.EXTRA_MEASURES):
        assert f"| {m} |" in md
    assert (tmp_path / "out" / "measure_evaluation.png").stat().st_size > 10_000
    lines = (tmp_path / "out" / "measure_evaluation.csv").read_text().splitlines()
    assert len(lines) == 1 + 5
