"""The benchmark report's numbers against values computed here, independently of :mod:`hardness.benchmark.report`:
the committed quick benchmark's tables against its ``members.csv``; and, on a run folder written here with known
scores and curves, the tables, ``measures.csv`` (against each MDP's measures computed one at a time) and the data
plotted in both figures (points, colours and curves read back from the matplotlib objects).
"""

from __future__ import annotations

import csv
import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

import hardness
from hardness.benchmark import report, sets
from hardness.benchmark.tables import MEMBER_FIELDS

QUICK = Path(__file__).resolve().parent.parent / "docs" / "tables" / "benchmark_quick"
SHORT = {"MiniGridEmpty": "MG-Empty", "MiniGridRooms": "MG-Rooms"}


def read_csv(path: Path) -> list[dict]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def tables_of(md: str) -> dict[str, tuple[list[str], list[list[str]]]]:
    """``{set: (header, rows)}`` of the first table under each ``## set`` heading of a report.md (cells stripped)."""
    out = {}
    for section in md.split("\n## ")[1:]:
        name, *lines = section.splitlines()
        start = next((i for i, line in enumerate(lines) if line.startswith("| MDP |")), None)
        if start is None:  # not a set's section (the aggregates)
            continue
        table = []
        for line in lines[start:]:
            if not line.startswith("|"):
                break
            table.append([c.strip() for c in line.strip().strip("|").split("|")])
        out[name] = (table[0], table[2:])
    return out


def expected_table2(members: list[dict], set_name: str, agents: list[str]) -> list[list[str]]:
    """Table 2 by hand: per MDP (in members.csv order, numbered within the family), per agent mean ± std (ddof 1) of
    the per-step regret with 3 decimals, bold where a learning agent's rounded mean is the row's lowest; the average
    row: mean ± std (ddof 0) of the per-MDP means."""
    scores = defaultdict(list)
    order = []
    for r in members:
        if r["set"] == set_name:
            scores[(r["mdp"], r["agent"])].append(float(r["normalized_regret_per_step"]))
            if r["mdp"] not in order:
                order.append(r["mdp"])
    rows, count, per_agent = [], defaultdict(int), defaultdict(list)
    for mdp in order:
        family = mdp.split("/")[0]
        count[family] += 1
        stats = {a: (np.mean(scores[(mdp, a)]), np.std(scores[(mdp, a)], ddof=1), len(scores[(mdp, a)]))
                 for a in agents}
        best = min(round(m, 3) for a, (m, _, _) in stats.items() if not a.startswith("random"))
        row = [f"{SHORT.get(family, family)} ({count[family]})"]
        for a in agents:
            m, sd, _ = stats[a]
            per_agent[a].append(m)
            bold = not a.startswith("random") and round(m, 3) == best
            row.append(f"**{m:.3f}** ± {sd:.3f}" if bold else f"{m:.3f} ± {sd:.3f}")
        n = min(s[2] for s in stats.values())
        rows.append(row + [f"{n}/{n}"])
    avg = [f"{np.mean(per_agent[a]):.3f} ± {np.std(per_agent[a]):.3f}" for a in agents]
    return rows + [["*Average*"] + avg + [""]]


def test_committed_quick_report_tables_are_the_members_scores():
    members = read_csv(QUICK / "members.csv")
    tables = tables_of((QUICK / "report.md").read_text())
    set_names = list(dict.fromkeys(r["set"] for r in members))
    assert sorted(tables) == sorted(set_names) and len(members) == 2 * 3 * 7 * 2
    for set_name in set_names:
        header, rows = tables[set_name]
        agents = header[1:-1]
        assert sorted(agents) == sorted({r["agent"] for r in members if r["set"] == set_name})
        assert rows == expected_table2(members, set_name, agents), set_name


# ---------------------------------------------------------------------------------------------------------------
# A run folder written here: known scores, curves and the measures of two MDPs
# ---------------------------------------------------------------------------------------------------------------

SET = "episodic quick test"
AGENTS = ("q_learning_episodic", "psrl_episodic", "random_episodic")
SEEDS = (0, 1)
N_STEPS = 100
STEPS = np.array([50, 100])


def fake_run(out: Path, rng: np.random.Generator) -> tuple[dict, dict]:
    """``plan.json``, ``members.csv`` and the batches' curves of a run of ``AGENTS`` on the set's DeepSea and
    RiverSwim: returns ``{(mdp, agent): per-seed regrets per step}`` and ``{(mdp, agent): [seeds, records]}``
    cumulative regrets."""
    labels = [i.label for i in sets.instances(SET) if i.label.split("/")[0] in ("DeepSea", "RiverSwim")]
    settings = dict(sets=[SET], agents={SET: list(AGENTS)}, seeds=list(SEEDS), n_steps=N_STEPS,
                    log_periods={SET: 50}, hparams_source="reference", emission=None)
    members = [[lab, s] for lab in labels for s in SEEDS]
    batches = [dict(id=f"b.{a}", key=f"k.{a}", set_name=SET, agent=a, members=members) for a in AGENTS]
    (out / "plan.json").write_text(json.dumps(dict(settings=settings, batches=batches)))
    (out / "runs").mkdir()
    regret, curves = {}, {}
    with (out / "members.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(MEMBER_FIELDS)
        for a in AGENTS:
            cum = rng.uniform(0, 50, (len(STEPS), len(members))).cumsum(0)  # [records, members]
            rnd = rng.uniform(0, 50, (len(STEPS), len(members))).cumsum(0)
            np.savez(out / "runs" / f"b.{a}.curves.npz", steps=STEPS, cumulative_regret=cum,
                     random_cumulative_regret=rnd)
            (out / "runs" / f"b.{a}.json").write_text(json.dumps(dict(key=f"k.{a}")))
            for i, (lab, s) in enumerate(members):
                score = float(rng.uniform(0.05, 0.95))
                regret.setdefault((lab, a), []).append(score)
                curves.setdefault((lab, a), []).append(cum[:, i])
                w.writerow([SET, lab, lab.split("/")[0], a, s, N_STEPS, 1.0, score * N_STEPS, score, 0.3 * N_STEPS,
                            0.4 * N_STEPS, 0.9, f"b.{a}"])
    return regret, {k: np.asarray(v) for k, v in curves.items()}


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    regret, curves = fake_run(out, np.random.default_rng(0))
    report.write_report(out)
    return out, regret, curves


def test_tables_of_a_run_are_its_scores(folder):
    out, regret, _ = folder
    members = read_csv(out / "members.csv")
    header, rows = tables_of((out / "report.md").read_text())[SET]
    assert header == ["MDP", *AGENTS, "seeds"]
    want = expected_table2(members, SET, list(AGENTS))
    want[-1][0] = "*Average of these 2 of 7*"
    assert rows == want
    assert [r[0] for r in rows[:2]] == ["DeepSea (1)", "RiverSwim (1)"]
    assert regret[("DeepSea/prms_0", "random_episodic")] == [float(r["normalized_regret_per_step"]) for r in members
                                                           if r["agent"] == "random_episodic"][:2]


def test_measures_csv_holds_each_mdp_s_measures_computed_alone(folder):
    out, _, _ = folder
    rows = read_csv(out / "measures.csv")
    assert [(r["set"], r["mdp"], int(r["seed"])) for r in rows] == sorted(
        (SET, lab, s) for lab in ("DeepSea/prms_0", "RiverSwim/prms_0") for s in SEEDS)
    instances = {i.label: i for i in sets.instances(SET)}
    for r in rows:
        mdp = instances[r["mdp"]].build(int(r["seed"]))
        d = float(hardness.diameter(mdp, variant=report.MEASURE_VARIANT).value)
        v = float(hardness.value_norm(mdp, variant=report.MEASURE_VARIANT).value)
        assert float(r["diameter"]) == pytest.approx(d, rel=1e-6), r
        assert float(r["value_norm"]) == pytest.approx(v, rel=1e-6), r
        assert math.isfinite(d) and d > 0 and v > 0


def test_hardness_figure_plots_the_measures_and_the_mean_regrets(folder):
    out, regret, _ = folder
    measures = defaultdict(list)
    for r in read_csv(out / "measures.csv"):
        measures[r["mdp"]].append((float(r["diameter"]), float(r["value_norm"])))
    labels = ["DeepSea/prms_0", "RiverSwim/prms_0"]
    xy = np.array([np.mean(measures[lab], axis=0) for lab in labels])
    fig = report.hardness_figure(report.summarize(out), SET)
    panels = [ax for ax in fig.axes if ax.get_title() in AGENTS]
    assert [ax.get_title() for ax in panels] == ["q_learning_episodic", "psrl_episodic"]  # learning agents only
    for ax in panels:
        points = ax.collections[0]
        np.testing.assert_allclose(points.get_offsets(), xy, rtol=1e-12)
        np.testing.assert_allclose(points.get_array(), [np.mean(regret[(lab, ax.get_title())]) for lab in labels],
                                   rtol=1e-12)


def test_curves_figure_plots_the_mean_cumulative_regret_from_the_origin(folder):
    out, _, curves = folder
    fig = report.curves_figure(report.summarize(out), SET)
    titles = {"DeepSea (1)": "DeepSea/prms_0", "RiverSwim (1)": "RiverSwim/prms_0"}
    panels = [ax for ax in fig.axes if ax.get_title() in titles]
    assert len(panels) == 2
    for ax in panels:
        lines = {line.get_label(): line for line in ax.get_lines()}
        assert sorted(lines) == sorted(AGENTS)
        for a in AGENTS:
            x, y = lines[a].get_data()
            np.testing.assert_array_equal(x, [0, *STEPS])
            np.testing.assert_allclose(y, [0.0, *curves[(titles[ax.get_title()], a)].mean(0)], rtol=1e-12)


# ---------------------------------------------------------------------------------------------------------------
# The late regret rate: piecewise-linear cumulative regrets with known slopes
# ---------------------------------------------------------------------------------------------------------------


def _late_folder(out: Path) -> None:
    """Two MDPs of ``SET``: the first with two seeds, the second with one, cumulative regret ``C(t) = r1 t`` up to
    step 60 and slope ``r2`` after it, normalising constants ``k``; a batch of another set, one unfinished and one
    of a stale key are left out."""
    labels = [i.label for i in sets.instances(SET) if i.label.split("/")[0] in ("DeepSea", "RiverSwim")]
    steps = np.array([20, 40, 60, 80, 100])
    members = [(labels[0], 0, 0.5, 2.0, 0.25), (labels[0], 1, 0.5, 1.0, 0.5), (labels[1], 0, 2.0, 0.1, 0.0)]
    curve = np.array([[r1 * min(t, 60) + r2 * max(t - 60, 0) for *_, r1, r2 in members] for t in steps])
    batches = [dict(id="b", key="k", set_name=SET, agent="q_learning_episodic", members=[m[:2] for m in members]),
               dict(id="other", key="k", set_name="episodic ergodic", agent="q_learning_episodic", members=[]),
               dict(id="unfinished", key="k", set_name=SET, agent="q_learning_episodic", members=[]),
               dict(id="stale", key="new", set_name=SET, agent="q_learning_episodic", members=[])]
    (out / "plan.json").write_text(json.dumps(dict(settings=dict(sets=[SET]), batches=batches)))
    (out / "runs").mkdir()
    rows = [dict(mdp=lab, seed=s, cumulative_regret=c, normalized_cumulative_regret=k * c,
                 normalized_regret_per_step=k * c / 100) for (lab, s, k, _, _), c in zip(members, curve[-1])]
    for name in ("b", "other", "stale"):
        np.savez(out / "runs" / f"{name}.curves.npz", steps=steps, cumulative_regret=curve * (name == "b"),
                 random_cumulative_regret=curve)
        (out / "runs" / f"{name}.json").write_text(json.dumps(dict(key="k", members=rows)))


def test_late_regret_is_the_slope_over_the_last_steps_and_its_projection(tmp_path):
    _late_folder(tmp_path)
    got = report.late_regret(tmp_path, SET, fraction=0.2, horizon=1000)
    assert list(got) == ["q_learning_episodic"]
    # Per member (end k C(100)/100, late k r2, projected k (C(100) + 900 r2) / 1000), then seeds, then MDPs.
    end = ((0.5 * 130 / 100 + 0.5 * 80 / 100) / 2 + 2.0 * 6 / 100) / 2
    late = ((0.5 * 0.25 + 0.5 * 0.5) / 2 + 0.0) / 2
    projected = ((0.5 * 355 / 1000 + 0.5 * 530 / 1000) / 2 + 2.0 * 6 / 1000) / 2
    np.testing.assert_allclose(got["q_learning_episodic"][:3], [end, late, projected], rtol=1e-12)
    assert got["q_learning_episodic"].n_mdps == 2
    # From step 40 on (fraction 0.6): the slope over 40..100 mixes r1 and r2.
    mixed = report.late_regret(tmp_path, SET, fraction=0.6)["q_learning_episodic"]
    assert mixed.late == pytest.approx(((0.5 * 50 / 60 + 0.5 * 40 / 60) / 2 + 2.0 * 2 / 60) / 2, rel=1e-12)
    assert math.isnan(mixed.projected)


def test_late_regret_refuses_a_fraction_or_horizon_it_cannot_use(tmp_path):
    _late_folder(tmp_path)
    for bad in (0, 1, 1.5, -0.2):
        with pytest.raises(ValueError, match="fraction must lie strictly between 0 and 1"):
            report.late_regret(tmp_path, SET, fraction=bad)
    with pytest.raises(ValueError, match="leaves fewer than two records"):
        report.late_regret(tmp_path, SET, fraction=0.05)
    with pytest.raises(ValueError, match="horizon must be at least the run's 100 steps; got 99"):
        report.late_regret(tmp_path, SET, horizon=99)


# ---------------------------------------------------------------------------------------------------------------
# Compute: the hours of batches.csv per (set, agent)
# ---------------------------------------------------------------------------------------------------------------


def test_compute_time_sums_each_pair_s_finished_batches_and_the_report_shows_them(tmp_path):
    """Two pairs planned, one with two finished batches on two hosts, the other with none; the sums by hand."""
    batches = [dict(id="a0", key="k", set_name=SET, agent="psrl_episodic", members=[["m", 0]] * 3),
               dict(id="a1", key="k", set_name=SET, agent="psrl_episodic", members=[["m", 1]] * 2),
               dict(id="b0", key="k", set_name=SET, agent="random_episodic", members=[["m", 0]] * 4)]
    (tmp_path / "plan.json").write_text(json.dumps(dict(settings=dict(sets=[SET]), batches=batches)))
    with pytest.raises(KeyError):  # a pair not in the plan is not counted; a planned one with nothing finished is
        report.compute_time(tmp_path)[(SET, "ucrl2")]
    assert report.compute_time(tmp_path)[(SET, "random_episodic")] == report.ComputeTime(0.0, 0.0, 0, 0, 4, ())
    rows = [dict(batch="a0", set=SET, agent="psrl_episodic", members=3, compile_s=12.5, run_s=3600.0, host="x"),
            dict(batch="a1", set=SET, agent="psrl_episodic", members=2, compile_s=7.5, run_s=1780.0, host="w")]
    with (tmp_path / "batches.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    got = report.compute_time(tmp_path)
    assert list(got) == [(SET, "psrl_episodic"), (SET, "random_episodic")]
    assert got[(SET, "psrl_episodic")] == report.ComputeTime(20.0, 5380.0, 2, 5, 5, ("w", "x"))
    assert got[(SET, "psrl_episodic")].hours == pytest.approx(1.5, rel=1e-15)
    table = report.compute_table(tmp_path).splitlines()
    assert table[2] == f"| {SET} | psrl_episodic | 2 | 5/5 | 0.01 | 1.49 | 1.50 | w, x |"
    assert table[3] == f"| {SET} | random_episodic | 0 | 0/4 | 0.00 | 0.00 | 0.00 |  |"
    assert table[4] == "| **total** |  | 2 | 5/9 | 0.01 | 1.49 | **1.50** |  |"


def test_a_report_s_compute_section_is_its_folder_s_compute_table(folder):
    out, _, _ = folder
    section = (out / "report.md").read_text().split("\n## Compute\n", 1)[1]
    assert report.compute_table(out) in section
    assert "| **total** |  | 0 | 0/" in section  # the fake run has no batches.csv: nothing counted
