"""The benchmark run (resumable, byte-identical after an interruption) and its report (Table 2-style tables, figures).

The run tests use a tiny version: two MDPs of the episodic quick-test set (RiverSwim 5 and DeepSea 10, two size
buckets), two cheap agents, two seeds, 200 steps. The deep run: RiverSwim 5 through the ``StateInfo`` emission, DQN
and the random agent, two seeds, 200 steps.
"""

import csv
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import threading
import time

import jax
import numpy as np
import pytest

import jaxmdp
from conftest import REPO
from hardness.benchmark import claims, plans, published, report, run, sets
from jaxmdp import runner

TINY = dict(sets=("episodic quick test",), agents=("q_learning_episodic", "random_episodic"), seeds=(0, 1),
            n_steps=200, log_period=50, n_buckets=2, hparams="reference", only=("RiverSwim", "DeepSea"))


@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("full")
    summary = run.run_benchmark(run.RunConfig(**TINY), out, progress=False)
    return out, summary


def test_full_run_writes_members_batches_and_runner_csvs(full_run):
    out, summary = full_run
    assert summary.finished and len(summary.ran) == 4 and not summary.reused  # 2 agents x 2 buckets
    with (out / "members.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(run.MEMBER_FIELDS)
    # set order, then MDP order in the set (DeepSea before RiverSwim), agents as given, seeds.
    assert [(r["mdp"], r["agent"], r["seed"]) for r in rows] == [
        (m, a, s) for m in ("DeepSea/prms_0", "RiverSwim/prms_0") for a in TINY["agents"] for s in ("0", "1")]
    for r in rows:
        assert int(r["steps"]) == 200
        assert float(r["normalized_regret_per_step"]) == pytest.approx(float(r["normalized_cumulative_regret"]) / 200)
        if r["agent"] == "random_episodic":  # the random agent's regret is the uniform policy's, exactly
            assert float(r["normalized_regret_per_step"]) == pytest.approx(
                float(r["random_normalized_regret_per_step"]), rel=1e-5)
    with (out / "batches.csv").open(newline="") as f:
        batches = list(csv.DictReader(f))
    assert len(batches) == 4 and all(float(b["run_s"]) > 0 and float(b["compile_s"]) > 0 for b in batches)
    assert {(b["host"], b["pid"]) for b in batches} == {(socket.gethostname(), str(os.getpid()))}  # who ran them
    for b in summary.ran:  # the runner's CSV: every member's 4 records (200 steps / 50)
        with (out / "runs" / f"{b}.csv").open(newline="") as f:
            recs = list(csv.DictReader(f))
        assert sorted({int(r["steps"]) for r in recs}) == [50, 100, 150, 200]
        assert len(recs) == 4 * len({r["member"] for r in recs})
        assert not (out / "runs" / f"{b}.ckpt.npz").exists()


def test_second_run_finishes_at_once_without_building_anything(full_run, monkeypatch):
    out, _ = full_run
    before = (out / "members.csv").read_bytes()

    def no_build(self, seed):
        raise AssertionError("a finished run must not build MDPs")

    monkeypatch.setattr(sets.Instance, "build", no_build)
    summary = run.run_benchmark(run.RunConfig(**TINY), out, progress=False)
    assert summary.finished and summary.ran == [] and len(summary.reused) == 4
    assert (out / "members.csv").read_bytes() == before


def test_late_regret_of_a_run_ends_at_its_scores_and_the_random_agent_keeps_its_rate(full_run):
    out, _ = full_run
    with (out / "members.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    late = report.late_regret(out, TINY["sets"][0], fraction=0.5, horizon=1000)
    assert sorted(late) == sorted(TINY["agents"])
    for agent, got in late.items():
        per_mdp = {}
        for r in rows:
            if r["agent"] == agent:
                per_mdp.setdefault(r["mdp"], []).append(float(r["normalized_regret_per_step"]))
        assert got.n_mdps == 2  # members.csv prints 10 significant digits
        assert got.end == pytest.approx(np.mean([np.mean(v) for v in per_mdp.values()]), rel=1e-9)
    # The uniform policy's expected regret grows by the same amount every episode, so its late rate and projection
    # are its score but for the episode that a record cuts (0.05% here; a slope over n or n - t0 would be 2x off).
    rnd = late["random_episodic"]
    assert rnd.late == pytest.approx(rnd.end, rel=2e-3) and rnd.projected == pytest.approx(rnd.end, rel=2e-3)


def test_interrupted_and_resumed_run_gives_the_same_members_csv(full_run, tmp_path):
    out, _ = full_run
    # 4 runner chunks per batch (50 steps each): stop after 2 chunks of the second batch, then after one more.
    first = run.run_benchmark(run.RunConfig(**TINY), tmp_path, progress=False, stop_at=(1, 2))
    assert not first.finished and len(first.ran) == 2
    assert (tmp_path / "runs" / f"{first.ran[1]}.ckpt.npz").exists()
    with (tmp_path / "members.csv").open(newline="") as f:
        assert len(list(csv.DictReader(f))) == 2  # the first batch: RiverSwim (the small bucket), two seeds
    second = run.run_benchmark(run.RunConfig(**TINY), tmp_path, progress=False, stop_at=(0, 1))
    assert not second.finished and second.ran == [first.ran[1]]
    third = run.run_benchmark(run.RunConfig(**TINY), tmp_path, progress=False)
    assert third.finished
    assert (tmp_path / "members.csv").read_bytes() == (out / "members.csv").read_bytes()
    b = first.ran[1]  # the interrupted batch's runner CSV has each record once
    with (tmp_path / "runs" / f"{b}.csv").open(newline="") as f, (out / "runs" / f"{b}.csv").open(newline="") as g:
        resumed, straight = list(csv.reader(f)), list(csv.reader(g))
    assert len(resumed) == len(straight)
    cut = straight[0].index("steps_per_second")
    assert [r[:cut] for r in resumed] == [r[:cut] for r in straight]


def test_more_agents_on_a_finished_folder_run_only_their_batches(full_run, tmp_path):
    # A batch's key holds its agent, members and settings, not the other agents: the first run's batches are reused.
    out, _ = full_run
    first = run.run_benchmark(run.RunConfig(**{**TINY, "agents": ("random_episodic",)}), tmp_path, progress=False)
    assert first.finished and len(first.ran) == 2
    second = run.run_benchmark(run.RunConfig(**TINY), tmp_path, progress=False)
    assert sorted(second.reused) == sorted(first.ran)
    assert len(second.ran) == 2 and all(".q_learning_episodic." in b for b in second.ran)
    assert (tmp_path / "members.csv").read_bytes() == (out / "members.csv").read_bytes()


def test_report_files_and_table(full_run):
    out, _ = full_run
    for stem in ("curves_episodic_quick_test", "hardness_episodic_quick_test"):
        assert (out / f"{stem}.png").stat().st_size > 1000 and (out / f"{stem}.pdf").stat().st_size > 1000
    md = (out / "report.md").read_text()
    table = [line for line in md.splitlines() if line.startswith("| ")]
    assert table[0] == "| MDP | q_learning_episodic | random_episodic | seeds |"
    assert [r.split(" | ")[0] for r in table[1:4]] == ["| DeepSea (1)", "| RiverSwim (1)", "| *Average of these 2 of 7*"]
    assert all("**" in r.split(" | ")[1] for r in table[1:3])  # the only learning agent is the row's best
    assert "\\begin{tabular}" in (out / "report.tex").read_text()
    with (out / "measures.csv").open(newline="") as f:
        measures = list(csv.DictReader(f))
    assert len(measures) == 4 and all(float(m["diameter"]) > 0 for m in measures)


def _fake_run(out, rows, agents, setting="episodic ergodic", emission=None):
    """A run folder holding only ``plan.json`` and ``members.csv`` (what the tables read)."""
    labels = sorted({r[0] for r in rows})
    settings = dict(sets=[setting], agents={setting: agents}, seeds=[0, 1], n_steps=100,
                    log_periods={setting: 100}, hparams_source="reference", emission=emission)
    batches = [dict(id=f"b{a}", key="k", set_name=setting, agent=a,
                    members=[[lab, s] for lab in labels for s in (0, 1)]) for a in agents]
    (out / "plan.json").write_text(json.dumps(dict(settings=settings, batches=batches)))
    with (out / "members.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(run.MEMBER_FIELDS)
        for label, agent, seed, score in rows:
            w.writerow([setting, label, label.split("/")[0], agent, seed, 100, 0, score * 100, score, 0, 0,
                        1, f"b{agent}"])


def test_table2_bold_on_row_minimum_average_row_and_paper_columns(tmp_path):
    agents = ["q_learning_episodic", "psrl_episodic", "random_episodic"]
    scores = {  # per (MDP, agent): the two seeds' per-step regrets
        ("DeepSea/prms_0", "q_learning_episodic"): (0.2, 0.4), ("DeepSea/prms_0", "psrl_episodic"): (0.1, 0.1),
        ("DeepSea/prms_0", "random_episodic"): (0.0, 0.0),  # the random agent is never bold
        ("Taxi/prms_1", "q_learning_episodic"): (0.5, 0.5), ("Taxi/prms_1", "psrl_episodic"): (0.6, 0.8),
        ("Taxi/prms_1", "random_episodic"): (0.9, 0.9),
    }
    _fake_run(tmp_path, [(m, a, s, x) for (m, a), xs in scores.items() for s, x in enumerate(xs)], agents)
    lines = report.markdown_table(report.summarize(tmp_path), "episodic ergodic").splitlines()
    assert lines[0] == ("| MDP | q_learning_episodic | psrl_episodic | random_episodic | q_learning_episodic (paper) "
                        "| psrl_episodic (paper) | seeds |")
    cells = [line.strip("| ").split(" | ") for line in lines[2:]]
    assert [c[0] for c in cells] == ["DeepSea (1)", "Taxi (2)", "*Average of these 2 of 20*"]
    std = np.std([0.2, 0.4], ddof=1)
    assert cells[0][1:4] == [f"0.300 ± {std:.3f}", "**0.100** ± 0.000", "0.000 ± 0.000"]
    assert cells[1][1:3] == ["**0.500** ± 0.000", f"0.700 ± {np.std([0.6, 0.8], ddof=1):.3f}"]
    assert cells[0][4:6] == ["0.64 ± 0.00", "0.01 ± 0.00"] and cells[1][4:6] == ["0.56 ± 0.02", "0.05 ± 0.00"]
    assert cells[0][6] == "2/2"
    # Average: mean and population std over the MDPs of the per-MDP means (Table 2's rule).
    assert cells[2][1] == f"{np.mean([0.3, 0.5]):.3f} ± {np.std([0.3, 0.5]):.3f}"
    # The paper's average by the same rule over the same two MDPs (not Table 2's average over its 20).
    assert cells[2][4:6] == [f"{np.mean([0.64, 0.56]):.2f} ± {np.std([0.64, 0.56]):.2f}",
                             f"{np.mean([0.01, 0.05]):.2f} ± {np.std([0.01, 0.05]):.2f}"]
    tex = report.latex_table(report.summarize(tmp_path), "episodic ergodic")
    assert "$\\mathbf{0.100} \\pm 0.000$" in tex and "q\\_learning\\_episodic" in tex
    assert "\\textit{Average of these 2 of 20}" in tex


def test_average_row_of_a_whole_set_is_table2s(tmp_path):
    labels = [i.label for i in sets.instances("episodic ergodic")]
    _fake_run(tmp_path, [(lab, "q_learning_episodic", s, 0.5) for lab in labels for s in (0, 1)],
              ["q_learning_episodic"])
    last = report.markdown_table(report.summarize(tmp_path), "episodic ergodic").splitlines()[-1]
    assert last.strip("| ").split(" | ")[:3] == ["*Average*", "0.500 ± 0.000", "0.81 ± 0.24"]


def test_published_average_rows_are_the_mean_and_std_of_the_rows():
    for setting, by_agent in published.TABLE2.items():
        assert list(by_agent) != [] and all(len(rows) == 20 for rows in by_agent.values())
        assert set(next(iter(by_agent.values()))) == {i.label for i in sets.instances(setting)}
        for agent, rows in by_agent.items():
            means = np.array([m for m, _ in rows.values()])
            m, s = published.TABLE2_AVERAGE[setting][agent]
            assert abs(means.mean() - m) <= 0.005 and abs(means.std() - s) <= 0.005
            for label, (mean, _) in rows.items():
                assert published.appendix_g(setting, agent, label).regret[0] == mean


# App. G's non-tabular table, cells read off the tex by hand: each differs from the cell above and below it in its
# column (checked below), so a transcription with a row shifted by one fails; the last row of every sub-table is
# pinned in full, so a column shifted from any row on fails too.
_LAST_ROWS = {
    ("episodic communicating", "Taxi/prms_1"): ((0.86, 0.01), (0.86, 0.01), (0.90, 0.02), (0.87, 0.01)),
    ("episodic ergodic", "Taxi/prms_1"): ((0.34, 0.02), (0.34, 0.02), (0.36, 0.04), (0.32, 0.02)),
    ("continuous communicating", "Taxi/prms_0"): ((0.92, 0.01), (0.92, 0.01), (0.93, 0.02), (0.81, 0.17)),
    ("continuous ergodic", "Taxi/prms_0"): ((0.78, 0.02), (0.78, 0.02), (0.81, 0.03), (0.55, 0.13)),
}
NONTABULAR_PINS = {
    **{(setting, f"{a}_{setting.split()[0]}", label): cell for (setting, label), row in _LAST_ROWS.items()
       for a, cell in zip(("actor_critic", "actor_critic_rnn", "boot_dqn", "dqn"), row)},
    ("episodic communicating", "dqn_episodic", "DeepSea/prms_0"): (0.05, 0.09),
    ("episodic communicating", "actor_critic_episodic", "FrozenLake/prms_0"): (0.12, 0.08),
    ("episodic communicating", "boot_dqn_episodic", "MiniGridRooms/prms_1"): (0.34, 0.39),
    ("episodic ergodic", "boot_dqn_episodic", "DeepSea/prms_0"): (0.23, 0.18),
    ("episodic ergodic", "actor_critic_episodic", "MiniGridEmpty/prms_6"): (0.27, 0.14),
    ("continuous communicating", "actor_critic_rnn_continuous", "DeepSea/prms_1"): (0.41, 0.50),
    ("continuous communicating", "actor_critic_continuous", "FrozenLake/prms_1"): (0.27, 0.17),
    ("continuous communicating", "dqn_continuous", "SimpleGrid/prms_3"): (0.01, 0.02),
    ("continuous ergodic", "dqn_continuous", "DeepSea/prms_0"): (0.22, 0.39),
    ("continuous ergodic", "dqn_continuous", "MiniGridRooms/prms_1"): (0.38, 0.27),
    ("continuous ergodic", "actor_critic_continuous", "RiverSwim/prms_3"): (0.33, 0.49),
}


def test_published_nontabular_rows_agents_and_pinned_cells():
    assert list(published.NONTABULAR) == list(published.NONTABULAR_AVERAGE) and set(published.NONTABULAR) == set(
        sets.SETTINGS)
    for setting, by_agent in published.NONTABULAR.items():
        kind = "episodic" if sets.is_episodic(setting) else "continuous"
        deep = [f"{a}_{kind}" for a in ("actor_critic", "actor_critic_rnn", "boot_dqn", "dqn")]
        assert list(by_agent) == deep == list(published.NONTABULAR_AVERAGE[setting])
        assert all(run.agent_registry.AGENTS[a].observation == "emission" for a in deep)
        for rows in by_agent.values():  # the set's 20 MDPs, in its order
            assert list(rows) == [i.label for i in sets.instances(setting)]
            assert all(0 <= m <= 1 and 0 <= sd <= 0.5 for m, sd in rows.values())
    assert len(NONTABULAR_PINS) == 27
    for (setting, agent, label), cell in NONTABULAR_PINS.items():
        assert published.nontabular(setting, agent, label) == cell, (setting, agent, label)
        column = list(published.NONTABULAR[setting][agent].values())
        k = list(published.NONTABULAR[setting][agent]).index(label)
        assert cell not in column[max(k - 1, 0):k] + column[k + 1:k + 2]  # the pin tells a shifted row apart
    assert published.nontabular("episodic ergodic", "q_learning_episodic", "DeepSea/prms_0") is None


def test_published_nontabular_average_rows_are_the_mean_and_population_std_of_the_rows():
    # Tolerance 0.007: the printed average is rounded to 0.01 (error <= 0.005), and it was computed from the unrounded
    # per-MDP means, whose printed roundings (each error uniform on +-0.005, sd 0.0029) move the mean of 20 by about
    # 0.0029 / sqrt(20) = 0.00065 (0.002 is 3 sd; the std moves by about as much).
    ddof1_misses = 0
    for setting, by_agent in published.NONTABULAR.items():
        for agent, rows in by_agent.items():
            means = np.array([m for m, _ in rows.values()])
            m, s = published.NONTABULAR_AVERAGE[setting][agent]
            assert published.regret_average(setting, agent) == (m, s)
            assert abs(means.mean() - m) <= 0.007 and abs(means.std() - s) <= 0.007, (setting, agent)
            ddof1_misses += abs(means.std(ddof=1) - s) > 0.007
    assert ddof1_misses >= 8  # the sample std (ddof 1) misses in half of the 16 columns: the paper used ddof 0
    assert published.NONTABULAR_AVERAGE["episodic communicating"]["dqn_episodic"] == (0.19, 0.22)


def test_paper_columns_of_the_deep_agents_need_the_papers_emission(tmp_path):
    agents = ["dqn_episodic", "boot_dqn_episodic", "random_episodic"]
    scores = {"DeepSea/prms_0": 0.1, "FrozenLake/prms_0": 0.3}
    rows = [(m, a, s, x) for m, x in scores.items() for a in agents for s in (0, 1)]
    _fake_run(tmp_path, rows, agents, setting="episodic communicating", emission="state_info")
    lines = report.markdown_table(report.summarize(tmp_path), "episodic communicating").splitlines()
    assert lines[0] == ("| MDP | dqn_episodic | boot_dqn_episodic | random_episodic | dqn_episodic (paper) "
                        "| boot_dqn_episodic (paper) | seeds |")
    cells = [line.strip("| ").split(" | ") for line in lines[2:]]
    assert [c[0] for c in cells] == ["DeepSea (1)", "FrozenLake (1)", "*Average of these 2 of 20*"]
    assert cells[0][4:6] == ["0.05 ± 0.09", "0.17 ± 0.24"] and cells[1][4:6] == ["0.02 ± 0.01", "0.25 ± 0.25"]
    # The paper's average over the same two MDPs (mean, ddof 0), not its printed average over 20.
    assert cells[2][4:6] == [f"{np.mean([0.05, 0.02]):.2f} ± {np.std([0.05, 0.02]):.2f}",
                             f"{np.mean([0.17, 0.25]):.2f} ± {np.std([0.17, 0.25]):.2f}"]
    appendix = report._appendix_rows(report.summarize(tmp_path), "episodic communicating", latex=False)[1]
    assert [r[5] for r in appendix[:3]] == ["0.05 ± 0.09", "0.17 ± 0.24", ""]  # regret (paper); none for random
    assert [r[8] for r in appendix[:3]] == ["", "", ""]  # no completed counts for the deep agents
    assert "App. G's non-tabular table" in report._paper_source("state_info")  # the report's header names it
    # Another emission: the paper has no numbers for it, so no paper column.
    _fake_run(tmp_path, rows, agents, setting="episodic communicating", emission="one_hot")
    header = report.markdown_table(report.summarize(tmp_path), "episodic communicating").splitlines()[0]
    assert "(paper)" not in header
    assert "no numbers" in report._paper_source("one_hot") and "Table 2" in report._paper_source(None)


def test_average_row_of_a_whole_set_of_a_deep_agent_is_the_papers(tmp_path):
    labels = [i.label for i in sets.instances("continuous ergodic")]
    _fake_run(tmp_path, [(lab, "dqn_continuous", s, 0.5) for lab in labels for s in (0, 1)], ["dqn_continuous"],
              setting="continuous ergodic", emission="state_info")
    last = report.markdown_table(report.summarize(tmp_path), "continuous ergodic").splitlines()[-1]
    assert last.strip("| ").split(" | ")[:3] == ["*Average*", "0.500 ± 0.000", "0.12 ± 0.14"]


def test_bad_configs_raise_clear_errors(tmp_path):
    with pytest.raises(ValueError, match="unknown benchmark set"):
        run.run_benchmark(run.RunConfig(sets=("episodic quick tst",)), tmp_path)
    with pytest.raises(ValueError, match="no set of"):
        run.plan(run.RunConfig(sets=("episodic quick test",), agents=("ucrl2",)))
    with pytest.raises(ValueError, match="unknown emission 'StateInf'; did you mean 'StateInfo'"):
        run.plan(run.RunConfig(sets=("episodic quick test",), emission="StateInf"))
    with pytest.raises(ValueError, match="observes emissions: pass --emission"):
        run.plan(run.RunConfig(sets=("episodic quick test",), agents=("dqn_episodic",)))
    with pytest.raises(ValueError, match="is tabular"):
        run.plan(run.RunConfig(sets=("episodic quick test",), agents=("q_learning_episodic",), emission="one_hot"))
    with pytest.raises(ValueError, match="keeps no MDP"):
        run.plan(run.RunConfig(sets=("episodic quick test",), only=("Nowhere",), hparams="reference"))
    with pytest.raises(ValueError, match="memory_limit must be a positive number of bytes"):
        run.plan(run.RunConfig(sets=("episodic quick test",), memory_limit=0))
    with pytest.raises(ValueError, match="agent_buckets names an unknown agent 'psrl'"):
        run.plan(run.RunConfig(sets=("episodic quick test",), agent_buckets={"psrl": 2}))
    with pytest.raises(ValueError, match=r"agent_buckets\['ucrl2'\] must be a positive integer; got 0"):
        run.plan(run.RunConfig(sets=("episodic quick test",), agent_buckets={"ucrl2": 0}))


def _buckets_of(batches) -> dict[str, list[list[str]]]:
    """Per agent, the MDP labels of its batches, in order."""
    out: dict[str, list[list[str]]] = {}
    for b in batches:
        out.setdefault(b.agent, []).append(sorted({label for label, _ in b.members}))
    return out


def test_planning_agents_get_their_own_size_buckets():
    """By default episodic PSRL (a dense posterior draw per episode) runs on PLANNING_BUCKETS' finer buckets of a set,
    the other agents on ``n_buckets``; each agent's batches are jaxmdp.size_buckets of the set with its count, and
    together hold every MDP once. ``agent_buckets={}`` gives every agent ``n_buckets``."""
    assert run.PLANNING_BUCKETS == {"psrl_episodic": 16}
    for set_name, agents in (("episodic ergodic", ("psrl_episodic", "q_learning_episodic")),
                             ("continuous communicating", ("ucrl2", "psrl_continuous"))):
        insts = sets.instances(set_name)
        mdps = [i.build(0) for i in insts]
        settings, batches = run.plan(run.RunConfig(sets=(set_name,), agents=agents, seeds=(0,), hparams="reference"))
        got = _buckets_of(batches)
        for agent in agents:
            count = run.PLANNING_BUCKETS.get(agent, 4)
            want = [sorted(insts[i].label for i in g) for g in jaxmdp.size_buckets(mdps, count)]
            assert got[agent] == want and len(want) == count
            assert [b.id for b in batches if b.agent == agent][-1].endswith(f".b{count - 1}")
        assert settings["agent_buckets"] == {a: 16 for a in agents if a in run.PLANNING_BUCKETS}
        _, same = run.plan(run.RunConfig(sets=(set_name,), agents=agents, seeds=(0,), hparams="reference",
                                         agent_buckets={}))
        assert all(len(groups) == 4 for groups in _buckets_of(same).values())


def test_run_benchmark_buckets_option_applies_to_every_agent():
    from hardness.cli import benchmark as cli
    default = cli.config_from_args(cli.build_parser().parse_args(["run", "--out", "x"]))
    assert default.buckets("psrl_episodic") == 16 and default.buckets("psrl_continuous") == 4
    given = cli.config_from_args(cli.build_parser().parse_args(["run", "--out", "x", "--buckets", "3"]))
    assert given.buckets("psrl_episodic") == given.buckets("q_learning_episodic") == 3
    quick = cli.config_from_args(cli.build_parser().parse_args(["run", "--out", "x", "--quick"]))
    assert quick.buckets("psrl_episodic") == quick.buckets("ucrl2") == 1


ONE_BUCKET = {**TINY, "agents": ("q_learning_episodic",), "n_buckets": 1}


@pytest.mark.nightly  # by default: test_runner_planning.py (results independent of the slots)
def test_a_batch_too_large_for_memory_is_split_with_the_same_results(tmp_path):
    # One bucket: RiverSwim 5 (5 states) and DeepSea 10 (55) in one batch of 4 members. Its chunk program needs about
    # 490 KiB, a member padded to DeepSea's shape about 125 KiB: a 195 KiB limit forces one split into halves of 2.
    whole = run.run_benchmark(run.RunConfig(**ONE_BUCKET), tmp_path / "whole", progress=False, report=False)
    assert whole.ran == ["episodic_quick_test.q_learning_episodic.b0"]
    config = run.RunConfig(**ONE_BUCKET, memory_limit=200_000)
    split = run.run_benchmark(config, tmp_path / "split", progress=False, report=False)
    assert split.finished and split.ran == [f"{whole.ran[0]}.s0", f"{whole.ran[0]}.s1"]
    plan = json.loads((tmp_path / "split" / "plan.json").read_text())
    assert [len(b["members"]) for b in plan["batches"]] == [2, 2]
    assert all(len(b["whole"]) == 4 for b in plan["batches"])
    # The RiverSwim half is padded to DeepSea's shape, as in the whole batch: the same numbers, to the last digit.
    rows = _member_rows(tmp_path / "whole")
    assert _member_rows(tmp_path / "split") == rows and len(rows) == 5
    again = run.run_benchmark(config, tmp_path / "split", progress=False, report=False)  # the split plan is reused
    assert again.ran == [] and again.reused == split.ran
    with pytest.raises(runner.ProgramTooLarge, match="a single member"):  # halves down to one member, then refuse
        run.run_benchmark(run.RunConfig(**ONE_BUCKET, memory_limit=1), tmp_path / "tiny", progress=False)
    with pytest.raises(runner.ProgramTooLarge, match="run fewer than its 2 members"):  # max_members: no split
        run.run_benchmark(run.RunConfig(**{**ONE_BUCKET, "max_members": 2}, memory_limit=1), tmp_path / "fixed",
                          progress=False)


def _member_rows(out):
    with (out / "members.csv").open(newline="") as f:
        return [r[:-1] for r in csv.reader(f)]  # all but the batch id


def test_a_batch_runs_in_parts_of_at_most_part_members_with_the_whole_batch_s_results(tmp_path):
    # One batch of 4 members: RiverSwim 5 and DeepSea 10, two seeds each. In parts of one member, split in halves
    # twice; each part padded like the whole, so every number is the whole batch's to the last digit.
    whole = run.run_benchmark(run.RunConfig(**ONE_BUCKET), tmp_path / "whole", progress=False, report=False)
    b = whole.ran[0]
    config = run.RunConfig(**ONE_BUCKET, part_members=1)
    parts = run.run_benchmark(config, tmp_path / "parts", progress=False, report=False)
    assert parts.finished and parts.ran == [f"{b}.s{i}.s{j}" for i in (0, 1) for j in (0, 1)]
    plan = json.loads((tmp_path / "parts" / "plan.json").read_text())
    assert [len(p["members"]) for p in plan["batches"]] == [1, 1, 1, 1]
    assert all(len(p["whole"]) == 4 for p in plan["batches"])
    rows = _member_rows(tmp_path / "whole")
    assert _member_rows(tmp_path / "parts") == rows and len(rows) == 5
    with (tmp_path / "parts" / "batches.csv").open(newline="") as f:
        assert [r["batch"] for r in csv.DictReader(f)] == parts.ran  # each part written when it finished
    again = run.run_benchmark(run.RunConfig(**ONE_BUCKET), tmp_path / "parts", progress=False, report=False)
    assert again.ran == [] and again.reused == parts.ran  # the parts stay parts without the option
    # A batch that has started (its checkpoint) continues whole rather than losing its steps.
    started = run.run_benchmark(run.RunConfig(**ONE_BUCKET), tmp_path / "started", progress=False, report=False,
                                stop_at=(0, 1))
    assert not started.finished and (tmp_path / "started" / "runs" / f"{b}.ckpt.npz").exists()
    rest = run.run_benchmark(config, tmp_path / "started", progress=False, report=False)
    assert rest.finished and rest.ran == [b]
    assert _member_rows(tmp_path / "started") == _member_rows(tmp_path / "whole")


def test_part_members_is_checked_and_given_by_the_command_line(tmp_path):
    from hardness.cli import benchmark as cli
    for bad in (0, -2, 1.5, True, "4"):
        with pytest.raises(ValueError, match=r"part_members must be a positive integer \(members per part"):
            run.plan(run.RunConfig(**ONE_BUCKET, part_members=bad))
    with pytest.raises(ValueError, match="part_members applies to a run here, not to one on Ray"):
        run.run_benchmark(run.RunConfig(**ONE_BUCKET, part_members=2), tmp_path, progress=False, ray=True)
    assert not (tmp_path / "plan.json").exists()  # refused before anything is written
    args = cli.build_parser().parse_args(["run", "--out", "x", "--part-members", "3"])
    assert cli.config_from_args(args).part_members == 3
    assert cli.config_from_args(cli.build_parser().parse_args(["run", "--out", "x"])).part_members is None


def test_a_run_writing_to_a_log_shows_its_progress_in_lines(tmp_path, capfd):
    """stderr not a terminal (pytest's capture, as ``nohup ... > log``): with ``log_every`` the run writes plain
    progress lines and its compilations, no redraws; without it nothing. The command line asks for a line every five
    minutes by default."""
    from hardness.cli import benchmark as cli
    run.run_benchmark(run.RunConfig(**ONE_BUCKET), tmp_path / "lines", log_every=1e-9, report=False)
    err = capfd.readouterr().err
    assert "\r" not in err
    assert re.search(r"^compiling the chunk program \.\.\. \d+\.\d s$", err, re.M)
    lines = re.findall(r"^benchmark: +(\d+)% ([\d.]+)/800 member-steps \[\d\d:\d\d elapsed, \d\d:\d\d left, [\d.]+k? "
                       r"member-steps/s, \S+: 4 members\]$", err, re.M)
    assert lines and lines[-1] == ("100", "800")  # 4 members x 200 steps, the last line at the end
    run.run_benchmark(run.RunConfig(**ONE_BUCKET), tmp_path / "none", report=False)
    assert capfd.readouterr().err == ""
    parse = cli.build_parser().parse_args
    assert parse(["run", "--out", "x"]).log_every == 300.0
    assert parse(["run", "--out", "x", "--log-every", "60"]).log_every == 60.0
    assert parse(["run", "--out", "x", "--log-every", "0"]).log_every is None
    for bad in ("-1", "inf", "soon"):
        with pytest.raises(SystemExit):
            parse(["run", "--out", "x", "--log-every", bad])
    assert "--log-every: must be a number of seconds >= 0" in capfd.readouterr().err


DEEP = dict(sets=("episodic quick test",), agents=("dqn_episodic", "random_episodic"), seeds=(0, 1), n_steps=200,
            log_period=50, n_buckets=1, only=("RiverSwim",), emission="StateInfo")


def test_deep_agents_run_on_the_state_info_block_mdps(full_run, tmp_path):
    summary = run.run_benchmark(run.RunConfig(**DEEP), tmp_path, progress=False, report=False)
    assert summary.finished and len(summary.ran) == 2
    plan = json.loads((tmp_path / "plan.json").read_text())
    assert plan["settings"]["emission"] == "state_info"  # the reference's class name, canonicalised
    # The deep agents have no tuned values (agents.md §7): "tuned" (the default) gives their defaults.
    assert plan["settings"]["hparams"]["dqn_episodic"] == run._hparams_repr(run.agent_registry.get(
        "dqn_episodic").default_hparams)
    with (tmp_path / "members.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["agent"], r["seed"]) for r in rows] == [(a, s) for a in DEEP["agents"] for s in ("0", "1")]
    # The random agent ignores its observations: on the BlockMDP its records are the tabular run's, bit for bit.
    with (full_run[0] / "members.csv").open(newline="") as f:
        tabular = {(r["agent"], r["seed"]): r for r in csv.DictReader(f) if r["mdp"] == "RiverSwim/prms_0"}
    for r in rows:
        if r["agent"] == "random_episodic":
            assert {k: v for k, v in r.items() if k != "batch"} == {
                k: v for k, v in tabular["random_episodic", r["seed"]].items() if k != "batch"}
        else:
            assert 0 <= float(r["normalized_regret_per_step"]) <= 1.5
    # The same plan under the kind's own name: the same batches, so a run with either name resumes the other.
    again = run.run_benchmark(run.RunConfig(**{**DEEP, "emission": "state_info"}), tmp_path, progress=False,
                              report=False)
    assert again.ran == [] and len(again.reused) == 2


def test_an_emission_run_pads_each_bucket_s_observations_into_one_batch():
    # The episodic quick set through state_info: observation widths 2 (RiverSwim) to 7 (Taxi). The deep agents run on
    # DEEP_BUCKETS' two buckets, each one batch, its members' observations zero-padded to the bucket's widest.
    config = run.RunConfig(sets=("episodic quick test",), agents=("dqn_episodic",), seeds=(0,), n_steps=100,
                           emission="state_info")
    settings, batches = run.plan(config)
    assert settings["observations"] == "padded" and config.buckets("dqn_episodic") == run.DEEP_BUCKETS[
        "dqn_episodic"] == 2
    assert [b.id for b in batches] == ["episodic_quick_test.dqn_episodic.b0", "episodic_quick_test.dqn_episodic.b1"]
    first = batches[0]
    grid = run.batch_grid(first, config)
    by_label = {i.label: i for i in sets.instances(first.set_name)}
    own = [run.to_block_mdp(by_label[label].build(seed), "state_info", seed) for label, seed in first.members]
    assert grid.mdps.obs_shape == (7,) and {b.obs_shape for b in own} == {(2,), (3,), (7,)}
    for i, block in enumerate(own):
        width = block.obs_shape[0]
        np.testing.assert_array_equal(grid.mdps.obs_mask[i], np.arange(7) < width)
        np.testing.assert_array_equal(grid.mdps.emissions[i, : block.H, : block.n_states, :width], block.emissions)
        np.testing.assert_array_equal(grid.mdps.emissions[i, ..., width:], 0.0)
    # A folder of an emission run from before the padding (no "observations" setting) holds another protocol.
    old = {k: v for k, v in settings.items() if k != "observations"}
    with pytest.raises(ValueError, match="another protocol .*observations: None there, 'padded' here"):
        plans.merge_settings(old, settings)


def test_observation_shape_is_the_block_mdp_s_without_building_its_table():
    # Every emission kind on the quick sets' MDPs of at most 60 states (RiverSwim, FrozenLake, DeepSea: one field to
    # three, grids rendered): the shape the plan groups by (emission_shape) is the built BlockMDP's, and an MDP that
    # cannot produce a kind raises the table's error. linear_optimal takes emission_shape's branch of linear_random
    # (the same feature count) and costs a value iteration per MDP, so it is left out.
    for set_name in ("episodic quick test", "continuous quick test"):
        for inst in sets.instances(set_name):
            mdp = inst.build(0)
            if mdp.n_states > 60:
                continue
            for kind in sorted(set(jaxmdp.EMISSION_KINDS) - {"linear_optimal"}):
                try:
                    want = run.to_block_mdp(mdp, kind, 0).obs_shape
                except ValueError as error:
                    with pytest.raises(ValueError, match=re.escape(str(error))):
                        run.observation_shape(mdp, kind, 0)
                    continue
                assert run.observation_shape(mdp, kind, 0) == want, (inst.label, kind)


def test_emission_names_and_keys():
    assert {run.canonical_emission(n) for n in run.REFERENCE_EMISSIONS} == set(jaxmdp.EMISSION_KINDS)
    assert all(run.canonical_emission(k) == k for k in jaxmdp.EMISSION_KINDS)
    mdp = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5)
    a, b, c = (run.to_block_mdp(mdp, "StateLinearRandom", s) for s in (3, 3, 4))
    np.testing.assert_array_equal(a.emissions, b.emissions)  # the member's seed fixes the features
    assert not np.allclose(a.emissions, c.emissions)
    direct = jaxmdp.block_mdp(mdp, "linear_random", key=jax.random.fold_in(jax.random.key(3), run.EMISSION_STREAM))
    np.testing.assert_array_equal(a.emissions, direct.emissions)


def test_reference_mode_runs_the_colosseum_agents_in_their_own_batches(full_run, tmp_path):
    # The same tiny run in reference mode (--agent-variant colosseum): its own batch keys, the reference-mode agent's
    # defaults recorded, the random agent (the same in both variants) unchanged bit for bit, Q-learning not.
    config = run.RunConfig(**{**TINY, "only": ("RiverSwim",), "agent_variant": "colosseum"})
    summary = run.run_benchmark(config, tmp_path, progress=False, report=False)
    assert summary.finished and len(summary.ran) == 2
    settings = json.loads((tmp_path / "plan.json").read_text())["settings"]
    assert settings["agent_variant"] == "colosseum"
    with (tmp_path / "members.csv").open(newline="") as f:
        ref = {(r["agent"], r["seed"]): r for r in csv.DictReader(f)}
    with (full_run[0] / "members.csv").open(newline="") as f:
        paper = {(r["agent"], r["seed"]): r for r in csv.DictReader(f) if r["mdp"] == "RiverSwim/prms_0"}
    assert set(ref) == set(paper)
    for key, r in ref.items():
        same = {k: v for k, v in r.items() if k != "batch"} == {k: v for k, v in paper[key].items() if k != "batch"}
        assert same == (key[0] == "random_episodic"), key
    paper_keys = {b["id"]: b["key"] for b in json.loads((full_run[0] / "plan.json").read_text())["batches"]}
    ref_keys = {b["id"]: b["key"] for b in json.loads((tmp_path / "plan.json").read_text())["batches"]}
    assert all(ref_keys[i] != paper_keys.get(i) for i in ref_keys)
    # Q-learning continuous in reference mode defaults to the reference's "confidence" 0.95 as its delta.
    assert run.hp_sources.hparams_for("q_learning_continuous", "reference", "colosseum").delta == 0.95
    assert run.hp_sources.hparams_for("q_learning_continuous", "reference").delta == 0.05
    with pytest.raises(ValueError, match="tabular agents only"):
        run.plan(run.RunConfig(**{**DEEP, "agent_variant": "colosseum"}))
    with pytest.raises(ValueError, match="variant must be 'paper' or 'colosseum'"):
        run.plan(run.RunConfig(**{**TINY, "agent_variant": "reference"}))


@pytest.mark.nightly  # by default: test_reference_mode.py
def test_the_reference_indicators_are_an_option_of_the_run(tmp_path):
    # --indicators colosseum: the runner's colosseum indicators (docs/measures.md §6) for every batch, recorded in the
    # plan and in the batch keys; the members' scores are those of a direct runner call with them, and differ from the
    # paper's indicators (the MiniGrid's episodes start in several states: the reference scores the last episode's
    # start, the paper the start distribution).
    cfg = dict(sets=("episodic quick test",), agents=("random_episodic",), seeds=(0, 1), n_steps=300,
               log_period=50, n_buckets=1, hparams="reference", only=("MiniGridEmpty",))
    scores, keys = {}, {}
    for variant in ("paper", "colosseum"):
        config = run.RunConfig(**cfg, indicator_variant=variant)
        out = tmp_path / variant
        summary = run.run_benchmark(config, out, progress=False, report=False)
        assert summary.finished
        assert json.loads((out / "plan.json").read_text())["settings"]["variant"] == variant
        with (out / "members.csv").open(newline="") as f:
            scores[variant] = [float(r["normalized_cumulative_regret"]) for r in csv.DictReader(f)]
        [batch] = run.plan(config)[1]
        keys[variant] = batch.key
        direct = runner.run(run.agent_registry.get("random_episodic"), run.batch_grid(batch, config), 300,
                            log_period=50, n_records=config.n_records, variant=variant)
        np.testing.assert_allclose(scores[variant], direct.column("normalized_cumulative_regret")[-1], rtol=1e-6)
    assert keys["paper"] != keys["colosseum"]
    assert all(abs(p - c) > 1e-3 for p, c in zip(scores["paper"], scores["colosseum"])), scores
    with pytest.raises(ValueError, match="indicator_variant must be 'paper' or 'colosseum'; got 'reference'"):
        run.plan(run.RunConfig(**cfg, indicator_variant="reference"))
    from hardness.cli import benchmark as cli
    parse = lambda argv: cli.build_parser().parse_args(["run", *argv])  # noqa: E731
    assert cli.config_from_args(parse(["--out", "x"])).indicator_variant == "paper"
    assert cli.config_from_args(parse(["--out", "x", "--indicators", "colosseum"])).indicator_variant == "colosseum"


def test_the_reference_s_convergence_stop_is_an_option_of_the_run(tmp_path, monkeypatch):
    # --stop-when-converged: every runner call of the run gets it; the plan and the batch keys name it only when it is
    # on, so the plans of runs without it keep their keys (and their finished batches).
    cfg = dict(sets=("episodic quick test",), agents=("random_episodic",), seeds=(0,), n_steps=100, log_period=50,
               n_buckets=1, hparams="reference", only=("RiverSwim",))
    off_settings, [off] = run.plan(run.RunConfig(**cfg))
    on_settings, [on] = run.plan(run.RunConfig(**cfg, stop_when_converged=True))
    assert "stop_when_converged" not in off_settings and on_settings["stop_when_converged"] is True
    assert {k: v for k, v in on_settings.items() if k != "stop_when_converged"} == off_settings
    assert on.key != off.key
    seen = []
    real = run.runner.run
    monkeypatch.setattr(run.runner, "run", lambda *a, **kw: seen.append(kw["stop_when_converged"]) or real(*a, **kw))
    assert run.run_benchmark(run.RunConfig(**cfg, stop_when_converged=True), tmp_path, progress=False,
                             report=False).finished
    assert seen == [True]
    with pytest.raises(ValueError, match="stop_when_converged must be True or False; got 'yes'"):
        run.plan(run.RunConfig(**cfg, stop_when_converged="yes"))
    from hardness.cli import benchmark as cli
    parse = lambda argv: cli.build_parser().parse_args(["run", *argv])  # noqa: E731
    assert cli.config_from_args(parse(["--out", "x", "--stop-when-converged"])).stop_when_converged
    assert not cli.config_from_args(parse(["--out", "x"])).stop_when_converged


def test_the_benchmark_command_reports_a_finished_run(full_run, capsys):
    # jaxmdp-benchmark report DIR (or --out DIR): the report of the run folder, the files on stdout, the compile-time
    # line on stderr; a folder without a run is refused.
    from hardness.cli import benchmark as cli

    out, _ = full_run
    (out / "report.md").unlink(missing_ok=True)
    assert cli.main(["report", str(out), "--no-compile-cache"]) == 0
    captured = capsys.readouterr()
    assert (out / "report.md").exists() and str(out / "report.md") in captured.out
    assert "of which compiling" in captured.err
    assert cli.main(["report", "--out", str(out), "--quiet", "--no-compile-cache"]) == 0
    assert capsys.readouterr().out == ""
    with pytest.raises(SystemExit, match="holds no benchmark run"):
        cli.main(["report", "--out", str(out / "runs"), "--no-compile-cache"])


# ---------------------------------------------------------------------------------------------------------------
# Several processes on one folder, shards, merged folders
# ---------------------------------------------------------------------------------------------------------------

#: A process of the two-process test: waits at a gate so that both start together, then runs the tiny benchmark with
#: each batch held a second longer (so that the processes overlap), and prints what it ran.
ONE_OF_TWO = """
import json, pathlib, sys, time
from hardness.benchmark import run
out, ready, gate = sys.argv[1], pathlib.Path(sys.argv[2]), pathlib.Path(sys.argv[3])
config = {k: tuple(v) if isinstance(v, list) else v for k, v in json.loads(sys.argv[4]).items()}
real = run._run_batch
def held_longer(*args, **kwargs):
    done = real(*args, **kwargs)
    time.sleep(1.0)
    return done
run._run_batch = held_longer
ready.touch()
while not gate.exists():
    time.sleep(0.02)
s = run.run_benchmark(run.RunConfig(**config), out, progress=False, report=False, poll_s=0.2)
print(json.dumps(dict(ran=s.ran, others=s.others, reused=s.reused)))
"""


def _events(out, batch_id):
    return [line.split()[1] for line in (out / "runs" / f"{batch_id}.log").read_text().splitlines()]


def _plan_ids(out):
    return [b["id"] for b in json.loads((out / "plan.json").read_text())["batches"]]


def test_two_processes_on_one_folder_run_each_batch_once_and_end_with_the_single_run_s_results(full_run, tmp_path):
    out = tmp_path / "shared"
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    procs = [subprocess.Popen([sys.executable, "-c", ONE_OF_TWO, str(out), str(tmp_path / f"ready{i}"),
                               str(tmp_path / "gate"), json.dumps(TINY)], cwd=REPO, env=env, text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE) for i in range(2)]
    deadline = time.monotonic() + 600
    while not all((tmp_path / f"ready{i}").exists() for i in range(2)):
        assert all(p.poll() is None for p in procs) and time.monotonic() < deadline, [p.communicate() for p in procs]
        time.sleep(0.05)
    (tmp_path / "gate").touch()
    outputs = [p.communicate(timeout=600) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outputs
    did = [json.loads(o.strip().splitlines()[-1]) for o, _ in outputs]
    ids = _plan_ids(full_run[0])
    # every batch ran in exactly one process, both processes ran some, and each saw the other's finish
    assert sorted(did[0]["ran"] + did[1]["ran"]) == sorted(ids) and did[0]["ran"] and did[1]["ran"]
    for i in range(2):
        assert sorted(did[i]["others"] + did[i]["reused"]) == sorted(did[1 - i]["ran"])
    for b in ids:
        assert _events(out, b) == ["claimed", "finished"], b
    with (out / "batches.csv").open(newline="") as f:
        who = {r["batch"]: (r["host"], int(r["pid"])) for r in csv.DictReader(f)}
    assert who == {b: (socket.gethostname(), procs[i].pid) for i in range(2) for b in did[i]["ran"]}
    assert (out / "members.csv").read_bytes() == (full_run[0] / "members.csv").read_bytes()
    assert not list((out / "runs").glob("*.claim")) and not list((out / "runs").glob("*.ckpt.npz"))


def test_a_run_takes_over_a_gone_holder_s_batch_and_waits_for_a_live_one(full_run, tmp_path):
    # Two batches (the random agent on two buckets): the first claimed by a process of this machine that has exited,
    # the second by a process of another machine that keeps beating until the first has finished and then 2 s more
    # (twice stale_s), then lets go. The run takes the first over at once, waits for the second, then runs it.
    config = run.RunConfig(**{**TINY, "agents": ("random_episodic",)})
    first, second = run.plan(config, tmp_path)[1]
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / f"{first.id}.claim").write_text(json.dumps(dict(
        host=socket.gethostname(), machine=claims.machine(), pid=dead.pid, token="t", started="", beat=0)))
    claim = tmp_path / "runs" / f"{second.id}.claim"
    released = []

    def elsewhere():
        beat, until = 0, None
        while until is None or time.monotonic() < until:
            claim.write_text(json.dumps(dict(host="elsewhere", machine="elsewhere/b/p", pid=1, token="e", beat=beat)))
            beat += 1
            if until is None and (tmp_path / "runs" / f"{first.id}.json").exists():
                until = time.monotonic() + 2.0
            time.sleep(0.05)
        released.append(time.monotonic())
        claim.unlink()

    holder = threading.Thread(target=elsewhere)
    holder.start()
    summary = run.run_benchmark(config, tmp_path, progress=False, report=False, poll_s=0.05, heartbeat_s=0.1,
                                stale_s=1.0)
    holder.join()
    assert summary.finished and summary.ran == [first.id, second.id] and released
    assert _events(tmp_path, first.id) == ["took", "finished"]
    assert _events(tmp_path, second.id) == ["claimed", "finished"]  # waited: a live holder is not taken over
    with (tmp_path / "members.csv").open(newline="") as f, (full_run[0] / "members.csv").open(newline="") as g:
        assert list(csv.reader(f))[1:] == [r for r in csv.reader(g) if r[3] == "random_episodic"]


def test_a_call_naming_fewer_agents_keeps_the_folder_s_results_and_another_protocol_is_refused(full_run, tmp_path):
    out = tmp_path / "folder"
    shutil.copytree(full_run[0], out)
    before = {name: (out / name).read_bytes() for name in ("plan.json", "members.csv")}
    summary = run.run_benchmark(run.RunConfig(**{**TINY, "agents": ("random_episodic",)}), out, progress=False)
    assert summary.finished and summary.ran == [] and len(summary.reused) == 2
    assert {name: (out / name).read_bytes() for name in before} == before  # both agents still, every member
    with pytest.raises(ValueError, match=r"another protocol \(n_steps: 200 there, 100 here\)"):
        run.run_benchmark(run.RunConfig(**{**TINY, "n_steps": 100}), out, progress=False)
    with pytest.raises(ValueError, match=r"hparams_source: 'reference' there, 'tuned' here"):
        run.plan(run.RunConfig(**{**TINY, "hparams": "tuned"}), out)
    assert {name: (out / name).read_bytes() for name in before} == before
    with pytest.raises(ValueError, match="shard must be"):
        run.run_benchmark(run.RunConfig(**TINY), out, progress=False, shard=(2, 2))


def _without_column(text: str, header: str, sep: str) -> str:
    """``text`` with the cells of the table column named ``header`` emptied (timings cannot repeat)."""
    lines, at = text.splitlines(), None
    for k, line in enumerate(lines):
        cells = line.split(sep)
        if header in [c.strip(" |\\") for c in cells]:
            at = [c.strip(" |\\") for c in cells].index(header)
        elif not line.strip():
            at = None  # the end of the table
        elif at is not None and len(cells) > at:
            lines[k] = sep.join(cells[:at] + [""] + cells[at + 1 :])
    return "\n".join(lines)


def test_two_shards_in_two_folders_merge_into_the_single_run(full_run, tmp_path):
    from hardness.cli import benchmark as cli

    single = full_run[0]
    ids = _plan_ids(single)
    halves = [run.run_benchmark(run.RunConfig(**TINY), tmp_path / f"s{i}", progress=False, shard=(i, 2))
              for i in range(2)]
    assert [h.ran for h in halves] == [[ids[0], ids[3]], [ids[1], ids[2]]]  # the snake: shards 0, 1, 1, 0
    assert all(h.finished for h in halves) and not (tmp_path / "s0" / "report.md").exists()
    merged = tmp_path / "merged"
    assert cli.main(["report", str(tmp_path / "s0"), str(tmp_path / "s1"), "--out", str(merged), "--quiet",
                     "--no-compile-cache"]) == 0
    for name in ("members.csv", "plan.json", "measures.csv"):
        assert (merged / name).read_bytes() == (single / name).read_bytes(), name
    timing = ("compile_s", "run_s", "member_steps_per_s", "agent_steps_per_s", "host", "pid")
    tables = []
    for folder in (single, merged):
        with (folder / "batches.csv").open(newline="") as f:
            tables.append([{k: v for k, v in r.items() if k not in timing} for r in csv.DictReader(f)])
    assert tables[0] == tables[1] and len(tables[0]) == 4
    md = [_without_column((f / "report.md").read_text(), "steps/s", " | ") for f in (single, merged)]
    assert md[0] == md[1] and "steps/s" in md[0] and md[0] != (single / "report.md").read_text()
    tex = [_without_column((f / "report.tex").read_text(), "steps/s", " & ") for f in (single, merged)]
    assert tex[0] == tex[1]
    assert {p.name for p in (merged / "runs").iterdir()} >= {f"{b}{x}" for b in ids for x in (".json", ".curves.npz")}
    with pytest.raises(SystemExit, match="name the merged folder with --out"):
        cli.main(["report", str(tmp_path / "s0"), str(tmp_path / "s1"), "--no-compile-cache"])
    parser = cli.build_parser()
    for bad in ("3/2", "x"):
        with pytest.raises(SystemExit):
            parser.parse_args(["run", "--quick", "--shard", bad, "--out", "x"])
    assert parser.parse_args(["run", "--quick", "--shard", "1/2", "--out", "x"]).shard == (1, 2)
