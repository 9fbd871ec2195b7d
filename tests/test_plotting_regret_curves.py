"""jaxmdp.plotting.draw_regret_curves: what the figure holds, read back from its artists and checked against a
run's CSV rows (RunResult.rows, the records written out), grouped and averaged here by hand: one line per group whose
y-data is the group's mean, a band whose vertices are the stated band (mean ± standard error, or quantiles), labels
naming the groups."""

from __future__ import annotations

import dataclasses
import math
import types
from collections import defaultdict

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure

import agents
import jaxmdp
from jaxmdp import plotting, runner
from jaxmdp.experiment.records import MEMBER_COLUMNS, RunResult
from jaxmdp.experiment.indicators import CSV_COLUMNS

STEPS = 200
SEEDS = (0, 1, 2)


def fake_run(agent, hparams, seed, mdps=None):
    """A RunResult of ``agent`` on two MDPs x ``hparams`` x three seeds with drawn records (increasing cumulative
    regrets that differ between members): the plotting reads only the records and the grid, so no run is needed."""
    mdps = mdps or [jaxmdp.make("RiverSwim", episodic=False, seed=0, size=3),
                    jaxmdp.make("SimpleGrid", episodic=False, seed=0, size=3)]
    grid = runner.product(mdps, hparams, SEEDS)
    B, steps = grid.n_members, np.arange(50, STEPS + 1, 50)
    rng = np.random.default_rng(seed)
    regret = np.cumsum(rng.random((len(steps), B)), axis=0)
    reward = steps[:, None] - regret
    values = np.stack([regret, reward, reward, regret / 2], axis=-1)
    constants = types.SimpleNamespace(optimal=np.ones(B), worst=np.zeros(B), random=np.full(B, 0.5))
    return RunResult(steps=steps, values=values, constants=constants, grid=grid, agent=agent, compile_s=0.0, run_s=1.0,
                     n_steps=STEPS, log_period=50, record_period=50, variant="paper")


@pytest.fixture(scope="module")
def runs():
    """"Q-learning" with two hyperparameter sets (different ``h_weight``) and "random" with one."""
    ql = agents.get("q_learning_continuous")
    rnd = agents.get("random_continuous")
    return (fake_run(ql.name, [ql.default_hparams, ql.default_hparams.replace(h_weight=0.5)], 0),
            fake_run(rnd.name, [rnd.default_hparams], 1))


def by_hand(result, column="cumulative_regret", key=("mdp", "hparams")):
    """``{group: (steps, [curve per member])}`` from the run's CSV rows, grouped by the named member columns."""
    header = MEMBER_COLUMNS + CSV_COLUMNS
    out = defaultdict(lambda: defaultdict(dict))
    for row in result.rows():
        r = dict(zip(header, row))
        out[tuple(r[k] for k in key)][r["member"]][r["steps"]] = r[column]
    groups = {}
    for g, members in out.items():
        steps = sorted(next(iter(members.values())))
        groups[g] = (np.asarray(steps, float), [[m[s] for s in steps] for m in members.values()])
    return groups


def sem_band(curves):
    """Mean, mean - s/sqrt(n), mean + s/sqrt(n) at every record, s the sample standard deviation, by hand."""
    n = len(curves)
    mean = [sum(c[t] for c in curves) / n for t in range(len(curves[0]))]
    sd = [math.sqrt(sum((c[t] - mean[t]) ** 2 for c in curves) / (n - 1)) for t in range(len(mean))]
    return np.asarray(mean), np.asarray([m - s / math.sqrt(n) for m, s in zip(mean, sd)]), \
        np.asarray([m + s / math.sqrt(n) for m, s in zip(mean, sd)])


def linear_quantile(values, q):
    v = sorted(values)
    pos = q * (len(v) - 1)
    lo = math.floor(pos)
    hi = min(lo + 1, len(v) - 1)
    return v[lo] + (pos - lo) * (v[hi] - v[lo])


def assert_band(collection, x, lo, hi):
    """The filled polygon's vertices are the points ``(x, lo)`` and ``(x, hi)`` and nothing outside them."""
    verts = np.concatenate([p.vertices for p in collection.get_paths()])
    for xi, a, b in zip(x, lo, hi):
        at = verts[np.isclose(verts[:, 0], xi)]
        assert np.isclose(at[:, 1], a, rtol=1e-9, atol=1e-9).any() and np.isclose(at[:, 1], b, rtol=1e-9,
                                                                                    atol=1e-9).any()
        assert np.all(at[:, 1] >= min(a, b) - 1e-9) and np.all(at[:, 1] <= max(a, b) + 1e-9)


def test_default_groups_are_everything_but_the_seed(runs):
    ql, _ = runs
    fig = plotting.draw_regret_curves(ql)
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    want = by_hand(ql)
    assert len(ax.lines) == len(want) == 4 and len(ax.collections) == 4
    labels = [ln.get_label() for ln in ax.lines]
    for (mdp, hp), (steps, curves) in want.items():
        # The agent is the same for all: not in the labels; the MDPs' family names tell them apart.
        k = labels.index(f"mdp={mdp.split('(')[0]}, hparams={hp}")
        line, poly = ax.lines[k], ax.collections[k]
        mean, lo, hi = sem_band(curves)
        np.testing.assert_allclose(line.get_xdata(), steps)
        np.testing.assert_allclose(line.get_ydata(), mean, rtol=1e-9)
        assert np.ptp(curves, axis=0).max() > 0  # the seeds differ, so the band has width
        assert_band(poly, steps, lo, hi)
        np.testing.assert_allclose(poly.get_facecolor()[0][:3], to_rgb(line.get_color()))
    assert "standard error" in ax.get_legend().get_title().get_text()


def test_quantile_band_and_grouping_by_a_hyperparameter(runs):
    ql, _ = runs
    fig = plotting.draw_regret_curves(ql, by="h_weight", column="normalized_cumulative_regret", band=(0.25, 0.75))
    ax = fig.axes[0]
    hand = by_hand(ql, "normalized_cumulative_regret", key=("hparams",))  # hparams 0 and 1 <-> h_weight 0.942, 0.5
    h_weight = {0: ql.grid.hparams.h_weight[0].item(), 1: 0.5}
    assert [ln.get_label() for ln in ax.lines] == [f"h_weight={h_weight[0]}", "h_weight=0.5"]
    for k, ((hp,), (steps, curves)) in enumerate(sorted(hand.items())):
        assert ax.lines[k].get_label() == f"h_weight={h_weight[hp]}"
        assert len(curves) == 6  # two MDPs x three seeds
        np.testing.assert_allclose(ax.lines[k].get_ydata(), np.mean(curves, axis=0), rtol=1e-9)
        lo = [linear_quantile([c[t] for c in curves], 0.25) for t in range(len(steps))]
        hi = [linear_quantile([c[t] for c in curves], 0.75) for t in range(len(steps))]
        assert_band(ax.collections[k], steps, lo, hi)
    assert "0.25-0.75 quantiles" in ax.get_legend().get_title().get_text()
    assert ax.get_ylabel() == "normalized cumulative regret"


def test_several_results_grouped_by_agent_on_given_axes(runs):
    ql, rnd = runs
    fig = Figure()
    ax = fig.add_subplot()
    assert plotting.draw_regret_curves([ql, rnd], by="agent", band="std", ax=ax) is fig
    assert [ln.get_label() for ln in ax.lines] == ["q_learning_continuous", "random_continuous"]
    for line, res in zip(ax.lines, (ql, rnd)):
        curves = [c for _, cs in by_hand(res, key=()).values() for c in cs]
        np.testing.assert_allclose(line.get_ydata(), np.mean(curves, axis=0), rtol=1e-9)
    sd = np.std([c for _, cs in by_hand(rnd, key=()).values() for c in cs], axis=0, ddof=1)
    steps = by_hand(rnd, key=())[()][0]
    assert_band(ax.collections[1], steps, ax.lines[1].get_ydata() - sd, ax.lines[1].get_ydata() + sd)
    # By every member key: one member per group, no band; a function groups as it says.
    fig = plotting.draw_regret_curves(rnd, by=("mdp", "seed"))
    assert len(fig.axes[0].lines) == 6 and len(fig.axes[0].collections) == 0
    fig = plotting.draw_regret_curves(rnd, by=lambda r, b: "first" if r.grid.seeds[b] == 0 else "rest")
    assert [ln.get_label() for ln in fig.axes[0].lines] == ["group=first", "group=rest"]


def test_mdps_of_one_family_keep_their_full_labels():
    rnd = agents.get("random_continuous")
    mdps = [jaxmdp.make("RiverSwim", episodic=False, seed=0, size=n) for n in (3, 4)]
    res = fake_run(rnd.name, [rnd.default_hparams], 2, mdps=mdps)
    labels = [ln.get_label() for ln in plotting.draw_regret_curves(res, by="mdp").axes[0].lines]
    assert labels == [f"mdp={m}" for m in res.grid.mdp_labels] and "size=4" in labels[1]


def test_errors_name_the_parameter(runs):
    ql, rnd = runs
    for kwargs, name in [
        (dict(band="iqr"), "band"), (dict(band=(0.8, 0.2)), "band"), (dict(by="colour"), "by"),
        (dict(by=3), "by"), (dict(column="regret"), "column"),
    ]:
        with pytest.raises(ValueError, match=name):
            plotting.draw_regret_curves(ql, **kwargs)
    with pytest.raises(ValueError, match="results"):
        plotting.draw_regret_curves([])
    shifted = dataclasses.replace(rnd, steps=rnd.steps + 1, agent="other")
    with pytest.raises(ValueError, match="record steps"):
        plotting.draw_regret_curves([rnd, shifted], by="mdp")
    assert len(plotting.draw_regret_curves([rnd, shifted]).axes[0].lines) == 4  # the default groups by agent too
