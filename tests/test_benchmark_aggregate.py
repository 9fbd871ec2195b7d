"""hardness.benchmark.aggregate: the interquartile mean against hand-computed cases (rliable's definition on counts
that are not multiples of 4), the stratified bootstrap against the exact enumeration of every resample of a tiny case,
stratification (runs never move between tasks), and the Markdown table built from members rows."""

from __future__ import annotations

import csv
import itertools
import math

import numpy as np
import pytest
import stat_checks

from hardness.benchmark import aggregate as ag


def test_iqm_hand_computed():
    # 8 scores: floor(8 / 4) = 2 dropped at each end; the middle four 3, 4, 5, 6 (of 1..8 shuffled) average 4.5.
    assert ag.iqm(np.array([[8.0, 1.0, 5.0, 3.0], [2.0, 7.0, 4.0, 6.0]])) == 4.5
    # Skewed: 0, 1, 2, 3, 4, 5, 50, 100 -> (2 + 3 + 4 + 5) / 4 (dropping one at each end would give 65 / 6).
    assert ag.iqm(np.array([[50.0, 0.0, 4.0, 2.0], [1.0, 100.0, 3.0, 5.0]])) == 3.5
    # 10 scores: floor(10 / 4) = 2 at each end, (2 + 3 + 4 + 5 + 6 + 60) / 6 (a 30% trim would give 4.5).
    assert ag.iqm(np.array([[0.0, 1, 2, 3, 4], [5, 6, 60, 80, 90]])) == pytest.approx(80 / 6, rel=1e-15)
    # 6 scores (not a multiple of 4): rliable's / scipy's trim drops floor(6 / 4) = 1 at each end and averages the
    # other four with equal weights, (1 + 2 + 4 + 8) / 4; fractional weights would give (1/2 + 2 + 4 + 8/2) / 3 = 3.5.
    assert ag.iqm(np.array([[0.0, 4.0, 100.0], [8.0, 1.0, 2.0]])) == 3.75
    # 7 scores: 1 dropped at each end, (2 + 3 + 4 + 5 + 6) / 5.
    assert ag.iqm(np.array([[7.0], [1.0], [6.0], [2.0], [5.0], [3.0], [4.0]])) == 4.0
    # 3 scores: nothing dropped (floor(3 / 4) = 0).
    assert ag.iqm(np.array([[1.0, 2.0, 30.0]])) == 11.0
    # The last two axes are pooled; leading axes are a batch.
    batch = np.stack([np.array([[8.0, 1.0, 5.0, 3.0], [2.0, 7.0, 4.0, 6.0]]), np.zeros((2, 4))])
    np.testing.assert_array_equal(ag.iqm(batch), [4.5, 0.0])
    assert ag.mean(np.array([[1.0, 2.0], [3.0, 10.0]])) == 4.0


def _exact_distribution(scores: np.ndarray, statistic) -> np.ndarray:
    """The statistic of every stratified resample of ``scores [N, M]``: all ``N**N`` run-index tuples of each task,
    combined over tasks (``N**(N M)`` resamples, each of probability ``N**-(N M)``), sorted."""
    N, M = scores.shape
    per_task = list(itertools.product(range(N), repeat=N))
    out = []
    for choice in itertools.product(per_task, repeat=M):
        resample = np.array([[scores[choice[m][n], m] for m in range(M)] for n in range(N)])
        out.append(statistic(resample))
    return np.sort(np.asarray(out))


@pytest.mark.statistical(p=3e-7)
def test_bootstrap_distribution_converges_to_the_exact_enumeration():
    # 3 seeds x 2 MDPs: 27**2 = 729 equally likely stratified resamples. The Dvoretzky-Kiefer-Wolfowitz inequality,
    # P(sup |F_B - F| > eps) <= 2 exp(-2 B eps^2) for any distribution F (discrete ones included), bounds the
    # bootstrap's empirical CDF around the exact one; eps is set so that this is 1e-7. A bootstrap that resampled
    # whole seeds across MDPs (27 resamples), or resampled the MDPs too, has another F and fails.
    scores = np.array([[0.1, 0.9], [0.4, 0.2], [0.7, 0.6]])
    for statistic in (ag.iqm, ag.mean):
        exact = _exact_distribution(scores, statistic)
        B = 20_000
        boot = np.sort(statistic(ag.stratified_resamples(scores, B, np.random.default_rng(stat_checks.seed(3)))))
        eps = math.sqrt(math.log(2 / 1e-7) / (2 * B))
        support = np.unique(exact)
        F_exact = np.searchsorted(exact, support, side="right") / exact.size
        F_boot = np.searchsorted(boot, support, side="right") / B
        assert np.max(np.abs(F_boot - F_exact)) <= eps, statistic.__name__
    # The interval's endpoints: with sup |F_B - F| <= eps the empirical alpha-quantile (interpolated between two
    # neighbouring order statistics, 1/B apart in probability) lies between the exact quantiles at alpha -+ (eps + 1/B).
    iv = ag.stratified_bootstrap(scores, ag.iqm, n_resamples=B, level=0.8, seed=stat_checks.seed(5))
    exact = _exact_distribution(scores, ag.iqm)

    def q(p):  # exact quantile function, inf{x: F(x) >= p}
        return exact[min(max(math.ceil(p * exact.size) - 1, 0), exact.size - 1)]

    d = eps + 1 / B
    assert q(0.1 - d) <= iv.low <= q(0.1 + d)
    assert q(0.9 - d) <= iv.high <= q(0.9 + d)
    assert iv.estimate == ag.iqm(scores) and (iv.n_runs, iv.n_tasks, iv.level) == (3, 2, 0.8)


def test_resamples_never_move_runs_between_tasks():
    # Task m's scores are 10 m + run, so every resampled entry names the task and the run it came from.
    N, M = 4, 3
    scores = 10.0 * np.arange(M)[None, :] + np.arange(N)[:, None]
    res = ag.stratified_resamples(scores, 500, np.random.default_rng(0))
    assert res.shape == (500, N, M)
    task, run = np.divmod(res, 10.0)
    np.testing.assert_array_equal(task, np.broadcast_to(np.arange(M), res.shape))  # column m only holds task m's runs
    assert set(np.unique(run)) == set(range(N))
    # Independently per task: the run drawn at position n differs between tasks in most resamples (a bootstrap that
    # drew one run index for all tasks would make the columns identical up to the task offset).
    same = np.all(run == run[:, :, :1], axis=(1, 2))
    assert same.mean() < 0.05


def test_bootstrap_is_reproducible_and_checks_its_arguments():
    scores = np.random.default_rng(1).random((5, 4))
    a = ag.stratified_bootstrap(scores, n_resamples=300, seed=2)
    assert a == ag.stratified_bootstrap(scores, n_resamples=300, seed=2)
    assert a != ag.stratified_bootstrap(scores, n_resamples=300, seed=3)
    assert a.low <= a.estimate <= a.high
    # The interval is the documented percentile interval of the documented resamples.
    boot = ag.iqm(ag.stratified_resamples(scores, 300, np.random.default_rng(2)))
    np.testing.assert_allclose([a.low, a.high], np.quantile(boot, [0.025, 0.975]), rtol=1e-12)
    # Drawn in blocks (2**21 scores each): the same stream as one draw.
    big = np.random.default_rng(3).random((40, 30))
    b = ag.stratified_bootstrap(big, ag.mean, n_resamples=2000, seed=4)
    boot = ag.mean(ag.stratified_resamples(big, 2000, np.random.default_rng(4)))
    np.testing.assert_allclose([b.low, b.high], np.quantile(boot, [0.025, 0.975]), rtol=1e-12)
    for call, name in [
        (lambda: ag.stratified_bootstrap(np.zeros(3)), "scores"),
        (lambda: ag.stratified_bootstrap(np.zeros((0, 3))), "scores"),
        (lambda: ag.stratified_bootstrap(np.array([[0.0, np.nan]])), "scores"),
        (lambda: ag.stratified_bootstrap(scores, n_resamples=0), "n_resamples"),
        (lambda: ag.stratified_bootstrap(scores, level=1.0), "level"),
        (lambda: ag.stratified_bootstrap(scores, level=True), "level"),
        (lambda: ag.stratified_bootstrap(scores, seed=-1), "seed"),
        (lambda: ag.stratified_resamples(scores, 10, 0), "rng"),
    ]:
        with pytest.raises(ValueError, match=name):
            call()


def _members(agents, mdps, seeds, score, set_name="episodic ergodic"):
    return [dict(set=set_name, mdp=m, agent=a, seed=str(s), normalized_regret_per_step=f"{score(a, m, s):.9g}")
            for a in agents for m in mdps for s in seeds]


def test_score_matrix_and_table_from_members_rows(tmp_path):
    score = lambda a, m, s: (0.1 if a == "psrl" else 0.9) + 0.01 * int(m[-1]) + 0.001 * s  # noqa: E731
    rows = _members(["psrl", "random"], ["M/0", "M/1", "M/2"], [0, 1, 2, 3], score)
    rows = [r for r in rows if not (r["agent"] == "random" and r["mdp"] == "M/2" and r["seed"] == "3")]  # unfinished
    rows += _members(["ucrl2"], ["C/0"], [0, 1], lambda a, m, s: 0.5 + s, set_name="continuous ergodic")
    x, mdps, seeds = ag.score_matrix(rows, "episodic ergodic", "psrl")
    assert mdps == ["M/0", "M/1"] and seeds == [0, 1, 2, 3]  # M/2 lacks a seed of the random agent: left out for all
    np.testing.assert_allclose(x, [[score("psrl", m, s) for m in mdps] for s in seeds])
    path = tmp_path / "members.csv"
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    md = ag.aggregate_table(path, n_resamples=200, seed=1)
    assert md == ag.aggregate_table(rows, n_resamples=200, seed=1)
    lines = md.splitlines()
    assert lines.index("### episodic ergodic") < lines.index("### continuous ergodic")
    assert "(the 2 of the 3 MDPs on which every agent has every seed)" in md
    for agent, set_name in (("psrl", "episodic ergodic"), ("random", "episodic ergodic"),
                            ("ucrl2", "continuous ergodic")):
        x, _, _ = ag.score_matrix(rows, set_name, agent)
        iq = ag.stratified_bootstrap(x, ag.iqm, n_resamples=200, seed=1)
        mu = ag.stratified_bootstrap(x, ag.mean, n_resamples=200, seed=1)
        row = (f"| {agent} | {iq.estimate:.3f} [{iq.low:.3f}, {iq.high:.3f}] "
               f"| {mu.estimate:.3f} [{mu.low:.3f}, {mu.high:.3f}] |")
        assert row in lines
    # psrl's 8 scores 0.100..0.113: IQM = mean of the middle four (0.102, 0.103, 0.110, 0.111) = 0.1065.
    assert math.isclose(ag.iqm(ag.score_matrix(rows, "episodic ergodic", "psrl")[0]), 0.1065, rel_tol=1e-9)
    with pytest.raises(ValueError, match="agent"):
        ag.score_matrix(rows, "episodic ergodic", "dqn")
    with pytest.raises(ValueError, match="set_name"):
        ag.score_matrix(rows, "nope", "psrl")
    with pytest.raises(ValueError, match="twice"):
        ag.aggregate_table(rows + rows[:1])
    with pytest.raises(ValueError, match="columns"):
        ag.aggregate_table([{"set": "s"}])
