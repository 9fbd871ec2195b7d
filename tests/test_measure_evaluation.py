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


def _point(x, y, seeds=None):
    """The point estimates ``(rho, tau_b)`` that :func:`me.correlations` reports for measure ``x`` against regret
    ``y`` (one row per entry; every row its own seed unless ``seeds`` is given)."""
    seeds = range(len(x)) if seeds is None else seeds
    rows = [dict(seed=s, m=float(a), agent_normalized_cumulative_regret=float(b)) for s, a, b in zip(seeds, x, y)]
    c = me.correlations(rows, ["m"], n_boot=1)[0]
    return c.spearman, c.kendall


def test_spearman_hand_worked():
    # y's ranks [1, 2, 3.5, 5, 3.5] (mid-ranks); centred x ranks [-2..2], centred y ranks [-2, -1, .5, 2, .5]:
    # rho = 8 / sqrt(10 * 9.5).
    assert math.isclose(_point([1, 2, 3, 4, 5], [5, 6, 7, 8, 7])[0], 8 / math.sqrt(95), rel_tol=1e-12)
    assert _point([1, 2, 3], [30, 20, 10])[0] == pytest.approx(-1.0, abs=1e-15)
    assert _point([1, 2, 3], [1, 4, 9])[0] == pytest.approx(1.0, abs=1e-15)  # any increasing map
    assert all(math.isnan(v) for v in _point([1, 1, 1], [1, 2, 3]))  # a constant input has no ranking


def test_kendall_tau_b_hand_worked():
    # 10 pairs: 8 concordant, 1 discordant ((8, 7)), 1 tied in y ((7, 7)): tau_b = 7 / sqrt(10 * 9).
    assert math.isclose(_point([1, 2, 3, 4, 5], [5, 6, 7, 8, 7])[1], 7 / math.sqrt(90), rel_tol=1e-12)
    # Ties in both: 1 concordant, 1 discordant, 2 tied in x, 2 tied in y: 0 / sqrt(4 * 4).
    assert _point([1, 1, 2, 2], [1, 2, 1, 2])[1] == pytest.approx(0.0, abs=1e-15)
    # x = [1, 2, 3, 4], y = [1, 3, 2, 4]: 5 concordant, 1 discordant, no ties: 4 / 6.
    assert math.isclose(_point([1, 2, 3, 4], [1, 3, 2, 4])[1], 4 / 6, rel_tol=1e-12)
    assert _point([3, 2, 1], [1, 2, 3])[1] == pytest.approx(-1.0, abs=1e-15)
    assert math.isnan(_point([2, 2], [1, 2])[1])
    # One finite row: no pair, no correlation.
    assert all(math.isnan(v) for v in _point([1.0, np.inf], [1, 2]))


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
    one = pytest.approx(1.0, abs=1e-12)  # scipy's rho of identical rankings is 1 up to rounding
    assert res["good"].spearman == one and res["good"].kendall == one
    assert res["good"].spearman_ci == (one, one) and res["good"].kendall_ci == (one, one)
    minus_one = pytest.approx(-1.0, abs=1e-12)
    assert res["bad"].kendall == minus_one and res["bad"].kendall_ci == (minus_one, minus_one)
    lo, hi = res["noise"].spearman_ci
    assert lo <= res["noise"].spearman <= hi and lo < hi
    assert res["some_inf"].n_rows == 16 and res["some_inf"].spearman == one  # infinite rows left out
    again = me.correlations(rows, ["noise"], n_boot=200)[0]
    assert again.spearman_ci == res["noise"].spearman_ci  # same seed, same intervals
    with pytest.raises(ValueError, match="lack the columns"):
        me.correlations(rows, ["nope"])


def _mid_ranks(v):
    """Ranks 1..n, ties sharing the mean of the ranks they span, by counting."""
    v = list(v)
    return [sum(u < a for u in v) + (sum(u == a for u in v) + 1) / 2 for a in v]


def _rho_by_hand(x, y):
    rx, ry = _mid_ranks(x), _mid_ranks(y)
    if len(rx) < 2:
        return math.nan
    mx, my = sum(rx) / len(rx), sum(ry) / len(ry)
    sxy = sum((a - mx) * (b - my) for a, b in zip(rx, ry))
    sxx, syy = sum((a - mx) ** 2 for a in rx), sum((b - my) ** 2 for b in ry)
    return sxy / math.sqrt(sxx * syy) if sxx > 0 and syy > 0 else math.nan


def _tau_b_by_hand(x, y):
    pairs = [(i, j) for i in range(len(x)) for j in range(i + 1, len(x))]
    sign = lambda d: (d > 0) - (d < 0)  # noqa: E731
    s = sum(sign(x[i] - x[j]) * sign(y[i] - y[j]) for i, j in pairs)
    tx, ty = sum(x[i] == x[j] for i, j in pairs), sum(y[i] == y[j] for i, j in pairs)
    denom = math.sqrt((len(pairs) - tx) * (len(pairs) - ty))
    return s / denom if denom > 0 else math.nan


def test_bootstrap_intervals_equal_a_brute_force_bootstrap_over_seeds():
    # The documented draw (default_rng(seed).integers(0, n_seeds, (n_boot, n_seeds)) over the sorted seeds), the rows
    # of the drawn seeds pooled, non-finite rows left out, the 2.5% and 97.5% percentiles (numpy's linear) of the
    # finite resampled correlations: computed here with hand-written ranks and pair counts.
    rng = np.random.default_rng(4)
    rows = []
    for s in (3, 8, 11, 20):
        for v in range(4):
            rows.append(dict(seed=s, agent_normalized_cumulative_regret=float(rng.integers(0, 3)),
                             m=float(rng.integers(0, 4)) if (s, v) != (8, 2) else math.inf))
    n_boot = 60
    c = me.correlations(rows, ["m"], n_boot=n_boot, seed=5)[0]
    draws = np.random.default_rng(5).integers(0, 4, size=(n_boot, 4))
    seeds = [3, 8, 11, 20]
    rho, tau = [], []
    for d in draws:
        pooled = [r for i in d for r in rows if r["seed"] == seeds[i] and math.isfinite(r["m"])]
        x, y = [r["m"] for r in pooled], [r["agent_normalized_cumulative_regret"] for r in pooled]
        rho.append(_rho_by_hand(x, y))
        tau.append(_tau_b_by_hand(x, y))
    for got, boot in ((c.spearman_ci, rho), (c.kendall_ci, tau)):
        finite = [b for b in boot if math.isfinite(b)]
        np.testing.assert_allclose(got, np.percentile(finite, [2.5, 97.5]), rtol=1e-12, atol=1e-12)
    finite_rows = [r for r in rows if math.isfinite(r["m"])]
    x, y = [r["m"] for r in finite_rows], [r["agent_normalized_cumulative_regret"] for r in finite_rows]
    assert c.n_rows == 15
    assert math.isclose(c.spearman, _rho_by_hand(x, y), rel_tol=1e-12)
    assert math.isclose(c.kendall, _tau_b_by_hand(x, y), rel_tol=1e-12)


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
        np.testing.assert_allclose(extra["bias_span"][k], float(hardness.bias_span(m).value), rtol=1e-5)
        np.testing.assert_allclose(extra["gap_constant"][k], float(hardness.gap_constant(m).value), rtol=1e-5)
    assert all(np.all(np.isfinite(extra[name])) for name in me.EXTRA_MEASURES)


def test_extra_measures_of_an_episodic_sweep_are_the_mismatch_and_nan():
    spec = scenarios.scenario_spec(1, "RiverSwim", episodic=True, seeds=[0], values=[0.0, 0.2], params=dict(size=5))
    rows = [dict(seed=0, value=v) for v in (0.2, 0.0)]
    extra = me.extra_measures(rows, sweep_cli.config_of(spec))
    for k, row in enumerate(rows):
        m = jaxmdp.make("RiverSwim", episodic=True, seed=0, **{**dict(spec.params), "p_rand": row["value"]})
        uniform = np.full((m.H, m.n_states, m.n_actions), 0.5, np.float32)
        np.testing.assert_allclose(extra["distribution_mismatch"][k],
                                   float(hardness.distribution_mismatch(m, None, uniform).value), rtol=1e-4)
    for name in me.CONTINUOUS_ONLY:
        assert np.all(np.isnan(extra[name])), name


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
    assert len(lines) == 1 + len(scenarios.MEASURES) + len(me.EXTRA_MEASURES)


def test_figure_wraps_the_scenarios_into_rows_of_at_most_columns_panels():
    corr = [me.Correlation("diameter", 0.5, (0.2, 0.8), 0.4, (0.1, 0.7), 10),
            me.Correlation("value_norm", math.nan, (math.nan, math.nan), math.nan, (math.nan, math.nan), 10)]
    fig = me.evaluation_figure({f"{k}: RiverSwim": corr for k in range(1, 5)}, columns=3)
    shown = [ax for ax in fig.axes if ax.get_visible()]
    assert len(fig.axes) == 6 and [ax.get_title() for ax in shown] == [f"{k}: RiverSwim" for k in range(1, 5)]
    assert {ax.get_subplotspec().rowspan.start for ax in shown} == {0, 1}
    with pytest.raises(ValueError, match="columns"):
        me.evaluation_figure({"1: RiverSwim": corr}, columns=0)
