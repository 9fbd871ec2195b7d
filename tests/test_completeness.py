"""hardness.analysis.completeness (rank correlations, the two-stage bootstrap, the leave-one-MDP-out pair) and the
benchmark wrapper hardness.analysis.completeness_benchmark with its command: against hand-computed cases, an exact
enumeration of the bootstrap on a tiny case and independent re-computations."""

from __future__ import annotations

import csv
import itertools
import math

import numpy as np
import pytest

from hardness.analysis import completeness as cp
from hardness.analysis import completeness_benchmark as cb
import stat_checks


def _mid_ranks(v):
    """Ranks 1..n, ties sharing the mean of the ranks they span, by counting."""
    v = list(v)
    return [sum(u < a for u in v) + (sum(u == a for u in v) + 1) / 2 for a in v]


def _rho(x, y):
    rx, ry = _mid_ranks(x), _mid_ranks(y)
    mx, my = sum(rx) / len(rx), sum(ry) / len(ry)
    sxy = sum((a - mx) * (b - my) for a, b in zip(rx, ry))
    sxx, syy = sum((a - mx) ** 2 for a in rx), sum((b - my) ** 2 for b in ry)
    return sxy / math.sqrt(sxx * syy) if sxx > 0 and syy > 0 else math.nan


def _tau_b(x, y):
    pairs = [(i, j) for i in range(len(x)) for j in range(i + 1, len(x))]
    sign = lambda d: int(d > 0) - int(d < 0)  # noqa: E731
    s = sum(sign(x[i] - x[j]) * sign(y[i] - y[j]) for i, j in pairs)
    tx, ty = sum(x[i] == x[j] for i, j in pairs), sum(y[i] == y[j] for i, j in pairs)
    denom = math.sqrt((len(pairs) - tx) * (len(pairs) - ty))
    return s / denom if denom > 0 else math.nan


def test_rank_correlations_hand_worked():
    # y's mid-ranks [1, 2, 3.5, 5, 3.5]: rho = 8 / sqrt(10 * 9.5); pairs: 8 concordant, 1 discordant, 1 tied in y:
    # tau_b = 7 / sqrt(10 * 9).
    rho, tau = cp.rank_correlations([1, 2, 3, 4, 5], [5, 6, 7, 8, 7])
    assert math.isclose(rho, 8 / math.sqrt(95), rel_tol=1e-12)
    assert math.isclose(tau, 7 / math.sqrt(90), rel_tol=1e-12)
    assert cp.rank_correlations([1, 1, 2, 2], [1, 2, 1, 2])[1] == pytest.approx(0.0, abs=1e-15)
    assert all(math.isnan(v) for v in cp.rank_correlations([1, 1, 1], [1, 2, 3]))
    assert all(math.isnan(v) for v in cp.rank_correlations([1], [2]))


def test_draws_shapes_and_bad_input():
    mdp_idx, seed_idx = cp.draw_resamples(4, 3, 10, seed=1)
    assert mdp_idx.shape == (10, 4) and seed_idx.shape == (10, 4, 3)
    assert mdp_idx.max() < 4 and seed_idx.max() < 3 and mdp_idx.min() >= 0
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="n_boot"):
            cp.draw_resamples(4, 3, bad)
    with pytest.raises(ValueError, match="measure and regret"):
        cp.correlation("m", np.zeros((3, 2)), np.zeros((3, 3)), (mdp_idx, seed_idx))
    with pytest.raises(ValueError, match="regret must be finite"):
        cp.correlation("m", np.zeros((3, 2)), np.full((3, 2), np.inf), (mdp_idx, seed_idx))


def _enumeration(n_mdps, n_seeds):
    """Every two-stage resample of ``n_mdps`` MDPs and ``n_seeds`` seeds, each equally likely: all ordered MDP draws,
    and for each all seed draws of every drawn MDP."""
    mdps = list(itertools.product(range(n_mdps), repeat=n_mdps))
    seed_rows = list(itertools.product(range(n_seeds), repeat=n_seeds))
    per_mdp = list(itertools.product(seed_rows, repeat=n_mdps))
    mdp_idx = np.asarray([m for m in mdps for _ in per_mdp])
    seed_idx = np.asarray([s for _ in mdps for s in per_mdp])
    return mdp_idx, seed_idx


# A tiny case: 3 MDPs x 2 seeds, measure and regret chosen so that resamples give many distinct correlations.
_MEASURE = np.array([[1.0, 3.0], [2.0, 2.0], [5.0, 0.0]])
_REGRET = np.array([[0.1, 0.5], [0.3, 0.2], [0.4, 0.35]])


def test_bootstrap_interval_equals_exact_enumeration():
    # With every equally likely resample passed as the draws, the interval is the percentiles of the exact
    # bootstrap distribution; recomputed here resample by resample with hand-written means, ranks and pair counts.
    draws = _enumeration(3, 2)
    assert len(draws[0]) == 27 * 64
    c = cp.correlation("m", _MEASURE, _REGRET, draws)
    rho, tau = [], []
    for mi, si in zip(*draws):
        x = [float(sum(_MEASURE[m][s] for s in seeds)) / 2 for m, seeds in zip(mi, si)]
        y = [float(sum(_REGRET[m][s] for s in seeds)) / 2 for m, seeds in zip(mi, si)]
        rho.append(_rho(x, y))
        tau.append(_tau_b(x, y))
    for got, boot in ((c.spearman_ci, rho), (c.kendall_ci, tau)):
        finite = [b for b in boot if math.isfinite(b)]
        np.testing.assert_allclose(got, np.percentile(finite, [2.5, 97.5]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(c.boot_spearman, rho, rtol=1e-12, atol=1e-12)
    x, y = _MEASURE.mean(axis=1), _REGRET.mean(axis=1)
    assert math.isclose(c.spearman, _rho(x, y), rel_tol=1e-12) and math.isclose(c.kendall, _tau_b(x, y),
                                                                              rel_tol=1e-12)
    assert c.n_mdps == 3


@pytest.mark.statistical(p=1e-7)
def test_random_draws_follow_the_exact_two_stage_distribution():
    # The statistic T = sum_j resampled measure mean + 10 * sum_j resampled regret mean depends on every draw of both
    # stages. Its exact distribution over the enumeration against n random resamples: the Dvoretzky-Kiefer-Wolfowitz
    # inequality bounds sup |F_n - F| > eps by 2 exp(-2 n eps^2) = ALPHA (for a discrete F too).
    def statistic(draws):
        return cp.resample_means(_MEASURE, *draws).sum(1) + 10 * cp.resample_means(_REGRET, *draws).sum(1)

    exact = np.sort(statistic(_enumeration(3, 2)))
    n = 40_000
    sample = np.sort(statistic(cp.draw_resamples(3, 2, n, seed=stat_checks.seed(3))))
    grid = np.unique(np.concatenate([exact, sample]))
    f_exact = np.searchsorted(exact, grid, side="right") / len(exact)
    f_sample = np.searchsorted(sample, grid, side="right") / n
    eps = math.sqrt(math.log(2 / stat_checks.ALPHA) / (2 * n))
    assert np.max(np.abs(f_exact - f_sample)) < eps


def test_non_finite_measures_are_left_out():
    measure = _MEASURE.copy()
    measure[1, 0] = np.inf
    draws = _enumeration(3, 2)
    c = cp.correlation("m", measure, _REGRET, draws)
    assert c.n_mdps == 2 and abs(c.spearman) == pytest.approx(1.0)
    # A resample keeps its draws of the finite MDPs: MDP 1's draws are dropped, the others' means kept.
    for b in (0, 5, 700):
        mi, si = draws[0][b], draws[1][b]
        keep = [k for k, m in enumerate(mi) if m != 1]
        x = [measure[mi[k]][si[k]].mean() for k in keep]
        y = [_REGRET[mi[k]][si[k]].mean() for k in keep]
        expected = _rho(x, y) if len(keep) >= 2 else math.nan
        got = c.boot_spearman[b]
        assert (math.isnan(expected) and math.isnan(got)) or math.isclose(got, expected, rel_tol=1e-12)


def _loo_by_hand(f, y, groups):
    """Leave-one-group-out predictions by the normal equations, written independently of lstsq."""
    target = np.log(y + cp.REGRET_OFFSET)
    out = []
    for j in range(len(y)):
        train = [i for i in range(len(y)) if groups[i] != groups[j]]
        cols = []
        for k in range(f.shape[1]):
            lo, hi = min(f[i, k] for i in train), max(f[i, k] for i in train)
            cols.append([(f[i, k] - lo) / (hi - lo) if hi > lo else 0.0 for i in range(len(y))])
        X = np.column_stack([np.ones(len(y)), *cols])
        A, b = X[train], target[train]
        beta = np.linalg.solve(A.T @ A, A.T @ b)
        out.append(X[j] @ beta)
    return np.asarray(out)


def test_loo_predictions_known_answer_and_independent_fit():
    rng = np.random.default_rng(0)
    d = rng.uniform(5, 50, 12)
    noise = rng.random(12)
    # log(y + offset) exactly linear in d: every held-out prediction is exact, whatever the useless second feature.
    y = np.exp(0.5 - 0.04 * d) - cp.REGRET_OFFSET
    pred = cp.loo_predictions(np.column_stack([d, noise]), y)
    np.testing.assert_allclose(pred, np.log(y + cp.REGRET_OFFSET), rtol=1e-9, atol=1e-9)
    f = np.column_stack([d, noise])
    y = rng.uniform(0.01, 0.9, 12)
    np.testing.assert_allclose(cp.loo_predictions(f, y), _loo_by_hand(f, y, np.arange(12)), rtol=1e-8, atol=1e-10)
    # Copies of a held-out MDP (a bootstrap resample) leave with it.
    groups = np.array([0, 1, 1, 2, 3, 3, 3, 4, 5, 6, 7, 8])
    f2, y2 = f[groups], y[groups]
    np.testing.assert_allclose(cp.loo_predictions(f2, y2, groups), _loo_by_hand(f2, y2, groups), rtol=1e-8,
                               atol=1e-10)
    # A measure constant on the training MDPs is ignored: the held-out MDP's prediction is that of the other measure
    # alone, whatever its own value of the constant one.
    flat = np.where(np.arange(12) < 11, 3.0, 0.0)
    alone = cp.loo_predictions(d[:, None], y)
    both = cp.loo_predictions(np.column_stack([d, flat]), y)
    assert both[11] == pytest.approx(alone[11], rel=1e-9)
    with pytest.raises(ValueError, match="features"):
        cp.loo_predictions(np.zeros(3), np.zeros(3))


def test_combined_correlation_orders_when_one_measure_explains_the_regret():
    rng = np.random.default_rng(2)
    d = rng.uniform(5, 50, (10, 1)) * np.ones((1, 3))
    v = rng.random((10, 3))
    regret = np.exp(-3 + 0.05 * d) + 0.0 * v
    draws = cp.draw_resamples(10, 3, 40, seed=0)
    c = cp.combined_correlation("d + v", [d, v], regret, draws)
    assert c.spearman == pytest.approx(1.0) and c.kendall == pytest.approx(1.0)
    # The point estimate is the rank correlation of the hand-fitted held-out predictions.
    y = rng.uniform(0.01, 0.9, (10, 3))
    c = cp.combined_correlation("d + v", [d, v], y, draws)
    f = np.column_stack([d.mean(1), v.mean(1)])
    pred = _loo_by_hand(f, y.mean(1), np.arange(10))
    assert math.isclose(c.spearman, _rho(list(pred), list(y.mean(1))), rel_tol=1e-9)


def test_best_shares():
    a = cp.Correlation("a", 0, (0, 0), 0, (0, 0), 3, np.array([0.5, 0.1, 0.3, np.nan]))
    b = cp.Correlation("b", 0, (0, 0), 0, (0, 0), 3, np.array([0.2, 0.4, 0.3, 0.9]))
    # Resample 4 has a NaN: left out; resample 3 is a tie: half each.
    assert cp.best_shares([a, b]) == {"a": pytest.approx(1.5 / 3), "b": pytest.approx(1.5 / 3)}


def test_measure_matrix_pairs_seeds_and_falls_back_to_the_mean():
    rows = [dict(set="s", mdp="A", seed=0, diameter=2.0), dict(set="s", mdp="A", seed=1, diameter=4.0),
            dict(set="s", mdp="B", seed=0, diameter=7.0), dict(set="t", mdp="A", seed=0, diameter=100.0)]
    got = cb.measure_matrix(rows, "s", ["A", "B"], [0, 1, 5], "diameter")
    np.testing.assert_array_equal(got, [[2.0, 4.0, 3.0], [7.0, 7.0, 7.0]])
    with pytest.raises(ValueError, match="no measure"):
        cb.measure_matrix(rows, "s", ["C"], [0], "diameter")


def _members(path, set_name, agent, mdps, seeds, regret):
    path.mkdir(parents=True, exist_ok=True)
    with (path / "members.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["set", "mdp", "family", "agent", "seed", "steps", "normalized_cumulative_regret"])
        for i, m in enumerate(mdps):
            for s in seeds:
                w.writerow([set_name, m, m.split("/")[0], agent, s, 1000, 1000 * regret(i, s)])
                w.writerow([set_name, m, m.split("/")[0], "random_continuous", s, 1000, 900])


def test_read_regrets_takes_the_folder_with_most_mdps_then_seeds(tmp_path):
    _members(tmp_path / "few", "continuous ergodic", "ucrl2", ["A/prms_0", "B/prms_0"], [0, 1], lambda i, s: 0.5)
    _members(tmp_path / "many", "continuous ergodic", "ucrl2", ["A/prms_0", "B/prms_0"], [0, 1, 2],
             lambda i, s: 0.1 * i + 0.01 * s)
    got = cb.read_regrets([tmp_path / "few", tmp_path / "many"])
    assert list(got) == [("continuous ergodic", "ucrl2")]
    entry = got[("continuous ergodic", "ucrl2")]
    assert entry["folder"] == tmp_path / "many"
    assert entry["regret"]["B/prms_0"] == {0: pytest.approx(0.1), 1: pytest.approx(0.11), 2: pytest.approx(0.12)}
    with pytest.raises(ValueError, match="members.csv"):
        cb.read_regrets([tmp_path / "none"])
    # A folder still being filled: 20 seeds, but on one MDP of the two; the finished 3-seed run keeps the pair,
    # whichever comes first. A complete 20-seed run takes it.
    _members(tmp_path / "partial", "continuous ergodic", "ucrl2", ["A/prms_0"], range(20), lambda i, s: 0.9)
    for order in ([tmp_path / "partial", tmp_path / "many"], [tmp_path / "many", tmp_path / "partial"]):
        assert cb.read_regrets(order)[("continuous ergodic", "ucrl2")]["folder"] == tmp_path / "many"
    _members(tmp_path / "full", "continuous ergodic", "ucrl2", ["A/prms_0", "B/prms_0"], range(20), lambda i, s: 0.2)
    got = cb.read_regrets([tmp_path / "many", tmp_path / "partial", tmp_path / "full"])
    assert got[("continuous ergodic", "ucrl2")]["folder"] == tmp_path / "full"


def test_command_writes_table_csv_and_figure(tmp_path):
    # Measures given in the cache (no MDP is built); the regret follows the diameter exactly and is the same at every
    # seed, so that every resample orders the MDPs as the diameter does (copies tie in both).
    mdps = [f"F{i}/prms_0" for i in range(8)]
    _members(tmp_path / "run", "continuous ergodic", "ucrl2", mdps, [0, 1, 2], lambda i, s: 0.05 * i + 0.01)
    out = tmp_path / "out"
    out.mkdir()
    rng = np.random.default_rng(0)
    rows = [dict(set="continuous ergodic", mdp=m, seed=0, **{k: float(rng.random()) for k in cb.MEASURES})
            for m in mdps]
    for i, r in enumerate(rows):
        r["diameter"] = 10.0 + i
    cb.write_measures(out / "measures.csv", rows)
    from hardness.cli import completeness as cli

    assert cli.main([str(tmp_path / "run"), "--out", str(out), "--n-boot", "20", "--quiet", "--no-compile-cache"]) == 0
    md = (out / "completeness.md").read_text()
    assert "### continuous ergodic, ucrl2 (8 MDPs, 3 seeds)" in md
    assert "| **diameter** | +1.00 [+1.00, +1.00] | +1.00 [+1.00, +1.00] |" in md
    for name in (*cb.MEASURES, "diameter + value_norm", "diameter_colosseum + value_norm_colosseum"):
        assert f"| {name} |" in md or f"| **{name}** |" in md
    lines = list(csv.DictReader((out / "completeness.csv").open()))
    assert len(lines) == len(cb.MEASURES) + 2 and lines[0]["n_seeds"] == "3"
    assert (out / "completeness_continuous_ergodic.png").stat().st_size > 10_000
