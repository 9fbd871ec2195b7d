"""Your own agent on the benchmark (docs/guide/own_agent.md): ``--agents module:NAME`` from a module outside the
package, its report beside the shipped agents' committed results without running them again, the refusal when the
protocols differ, a run folder as the baseline, and the tuner writing to its output folder."""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest

import agents
from agents import search_spaces
from conftest import REPO
from hardness.benchmark import baselines, hparams, published, report, run, sets
from hardness.benchmark.tables import MEMBER_FIELDS
from hardness.cli import _common
from hardness.cli import benchmark as cli

TABLES = REPO / "docs" / "tables"

# A user's module, written from an empty file: an epsilon-greedy Q-learner (episodic), registered with its search
# space on import (the guide's agent).
def _user_module() -> str:
    # The notebook's agent module (notebooks/src/06_benchmark_your_agent.py), so that the test and the notebook show
    # one agent; the test adds a name that is not an Agent for the refusals.
    source = (REPO / "notebooks" / "src" / "06_benchmark_your_agent.py").read_text()
    start = source.index('MODULE = """') + len('MODULE = """')
    return source[start : source.index('"""', start)] + "\nNOT_AN_AGENT = 3\n"


USER_MODULE = _user_module()


@pytest.fixture
def user_dir(tmp_path, monkeypatch, registry):
    """A folder outside the package holding the user's module, as the current directory (its module name is unique
    to the test, so that no earlier import of it is reused)."""
    folder = tmp_path / "my_project"
    folder.mkdir()
    name = f"my_agents_{tmp_path.name.replace('-', '_')}"
    (folder / f"{name}.py").write_text(USER_MODULE)
    monkeypatch.chdir(folder)
    monkeypatch.syspath_prepend(str(folder))
    return folder, name


def _committed_cell(folder: str, set_name: str, mdp: str, agent: str, seeds) -> tuple[float, float]:
    """Mean and std (ddof 1) of an agent's committed scores, read from the run folder itself (not the package
    data)."""
    with (TABLES / folder / "members.csv").open(newline="") as f:
        x = [float(r["normalized_regret_per_step"]) for r in csv.DictReader(f)
             if r["set"] == set_name and r["mdp"] == mdp and r["agent"] == agent and int(r["seed"]) in seeds]
    assert len(x) == len(seeds)
    return float(np.mean(x)), float(np.std(x, ddof=1))


def _row(report_md: str, section: str, first_cell: str) -> list[str]:
    """The cells of the first table row starting with ``first_cell`` in the report's section ``section``."""
    text = report_md.split(f"## {section}\n", 1)[1]
    line = next(x for x in text.splitlines() if x.startswith(f"| {first_cell} |"))
    return [c.strip() for c in line.strip("|").split("|")]


@pytest.mark.slow
def test_a_user_agent_from_a_module_outside_the_package_meets_the_committed_results(user_dir, capsys):
    folder, module = user_dir
    out = folder / "bench"
    argv = ["run", "--quick", "--mdps", "RiverSwim", "--agents", f"{module}:EPSILON_GREEDY", "--baseline",
            "committed", "--out", str(out), "--quiet", "--no-compile-cache"]
    # A protocol that differs from every committed one is refused before anything runs, naming what differs.
    with pytest.raises(SystemExit, match=r"protocol differs \(.*n_steps 500 here, 1000 there"):
        cli.main([*argv[:2], "--steps", "500", *argv[2:]])
    assert not out.exists()
    assert cli.main(argv) == 0
    md = (out / "report.md").read_text()
    header = _row(md, "episodic quick test", "MDP")
    assert header == ["MDP", "epsilon_greedy_q", "q_learning_episodic (committed)", "psrl_episodic (committed)",
                      "random_episodic (committed)", "seeds"]
    row = _row(md, "episodic quick test", "RiverSwim (1)")
    for k, agent in enumerate(("q_learning_episodic", "psrl_episodic", "random_episodic")):
        m, sd = _committed_cell("benchmark_quick", "episodic quick test", "RiverSwim/prms_0", agent, (0, 1))
        assert re.sub(r"\*", "", row[2 + k]) == f"{m:.3f} ± {sd:.3f}"
    with (out / "members.csv").open(newline="") as f:
        mine = [float(r["normalized_regret_per_step"]) for r in csv.DictReader(f)]
    assert len(mine) == 2 and re.sub(r"\*", "", row[1]) == f"{np.mean(mine):.3f} ± {np.std(mine, ddof=1):.3f}"
    assert "Hyperparameters of `epsilon_greedy_q`: epsilon=0.1, learning_rate=0.5" in md
    assert "from `docs/tables/benchmark_quick`" in md and "Aggregates across MDPs" in md
    assert "| q_learning_episodic (committed) |" in md.split("## Aggregates across MDPs", 1)[1]
    # Only the user's agent ran: no batch of a shipped agent.
    assert {p.name.split(".")[1] for p in (out / "runs").glob("*.json")} == {"epsilon_greedy_q"}


def test_an_agent_is_named_by_module_or_by_file_and_bad_names_are_refused(user_dir):
    folder, module = user_dir
    assert _common.load_agent(f"{module}:EPSILON_GREEDY") == "epsilon_greedy_q"
    assert agents.get("epsilon_greedy_q").name == "epsilon_greedy_q"
    assert dict(search_spaces.SEARCH_SPACES["epsilon_greedy_q"]) == {"epsilon": (0.01, 0.3),
                                                                      "learning_rate": (0.05, 1.0)}
    assert _common.load_agent("ucrl2") == "ucrl2"
    other = folder / "sub"
    other.mkdir()
    (other / "elsewhere.py").write_text(USER_MODULE.replace('"epsilon_greedy_q"', '"epsilon_greedy_file"'))
    assert _common.load_agent(f"{other / 'elsewhere.py'}:EPSILON_GREEDY") == "epsilon_greedy_file"
    with pytest.raises(ValueError, match="cannot import 'no_such_module'"):
        _common.load_agent("no_such_module:AGENT")
    with pytest.raises(ValueError, match="has no 'EPSILON_GREDY'; did you mean 'EPSILON_GREEDY'"):
        _common.load_agent(f"{module}:EPSILON_GREDY")
    with pytest.raises(ValueError, match="NOT_AN_AGENT is a int, not a jaxmdp.agent_interface.Agent"):
        _common.load_agent(f"{module}:NOT_AN_AGENT")
    with pytest.raises(ValueError, match="no file"):
        _common.load_agent(f"{folder / 'missing.py'}:X")


def _settings(**config) -> tuple[dict, dict]:
    """The plan settings of a run (no MDP built) and its MDP labels per set."""
    cfg = run.RunConfig(**config)
    settings = run._settings(cfg, run._check(cfg))
    labels = {s: [i.label for i in sets.instances(s) if not cfg.only or i.label in cfg.only]
              for s in settings["sets"]}
    return settings, labels


def test_the_committed_full_budget_results_are_chosen_by_protocol(registry):
    registry.register(dataclasses.replace(agents.AGENTS["random_continuous"], name="my_random_c"))
    full = dict(sets=("continuous ergodic",), agents=("my_random_c",), n_steps=500_000)
    beside = baselines.select(*_settings(**full, seeds=tuple(range(20))), "committed")
    assert beside.agents == {"continuous ergodic": ["ucrl2", "q_learning_continuous", "random_continuous",
                                                    "psrl_continuous"]}
    communicating = baselines.select(*_settings(**{**full, "sets": ("continuous communicating",)},
                                                seeds=tuple(range(20))), "committed")
    assert communicating.agents["continuous communicating"] == ["ucrl2", "q_learning_continuous", "random_continuous",
                                                                "psrl_continuous"]
    registry.register(dataclasses.replace(agents.AGENTS["random_episodic"], name="my_random_e"))
    episodic = baselines.select(*_settings(sets=("episodic communicating",), agents=("my_random_e",),
                                           n_steps=500_000, seeds=tuple(range(20))), "committed")
    assert episodic.agents["episodic communicating"] == ["q_learning_episodic", "random_episodic", "psrl_episodic"]
    # PSRL at 20 seeds there too; only the deep agents' runs (20 000 steps) are left out.
    assert sorted(a for _, a in episodic.left_out) == ["actor_critic_episodic", "actor_critic_rnn_episodic",
                                                       "dqn_episodic"]
    two = baselines.select(*_settings(**full, seeds=(0, 1)), "committed")  # seeds 0-1 of the 20-seed run
    assert two.agents["continuous ergodic"] == ["ucrl2", "q_learning_continuous", "random_continuous",
                                                "psrl_continuous"]
    cell = two.scores[("continuous ergodic", "RiverSwim/prms_0", "ucrl2")]["normalized_regret_per_step"]
    m, sd = _committed_cell("benchmark_continuous_full_20seeds", "continuous ergodic", "RiverSwim/prms_0", "ucrl2",
                            (0, 1))
    assert np.mean(cell) == pytest.approx(m, abs=1e-9) and np.std(cell, ddof=1) == pytest.approx(sd, abs=1e-9)
    # Each part of the protocol that differs is named; nothing comparable is refused.
    for change, named in [(dict(n_steps=100_000), "n_steps 100000 here, 500000 there"),
                          (dict(indicator_variant="colosseum"), "indicator_variant 'colosseum' here, 'paper' there"),
                          (dict(log_period=50), "log_period 50 here, 100 there"),
                          (dict(stop_when_converged=True), "stop_when_converged True here, False there"),
                          (dict(seeds=tuple(range(30))), "seeds 0-29 here, 0-19 there")]:
        with pytest.raises(ValueError, match=re.escape(named)):
            baselines.select(*_settings(**{**full, "seeds": tuple(range(20)), **change}), "committed")
    # Another hyperparameter source: an agent whose values it changes is left out, naming them; the others stay
    # (continuous Q-learning's and PSRL's tuned values are the reference's, their searches' winner; the random agent
    # has none).
    ref = baselines.select(*_settings(**full, seeds=tuple(range(20)), hparams="reference"), "committed")
    assert hparams.load_tuned()["q_learning_continuous"]["winner"] == "reference"
    assert hparams.load_tuned()["psrl_continuous"]["winner"] == "reference"
    assert ref.agents["continuous ergodic"] == ["q_learning_continuous", "random_continuous", "psrl_continuous"]
    assert ref.left_out[("continuous ergodic", "ucrl2")][0].startswith(
        "hyperparameters: --hparams reference gives ucrl2 alpha_p=0.9883750006754203")
    registry.register(dataclasses.replace(agents.AGENTS["random_continuous"], name="my_deep_c",
                                          observation="emission"))
    with pytest.raises(ValueError, match="emission 'state_info' here, None there"):
        baselines.select(*_settings(sets=("continuous ergodic",), agents=("my_deep_c",), n_steps=500_000,
                                    seeds=(0,), emission="state_info"), "committed")


def test_the_report_sets_the_committed_full_budget_results_and_the_papers_beside_a_new_agent(registry, tmp_path):
    # A full-protocol run of a new agent, its members made up (no run): the report shows the committed agents'
    # numbers and the paper's beside it, on the run's two MDPs.
    registry.register(dataclasses.replace(agents.AGENTS["random_continuous"], name="my_random_c"))
    only = ("RiverSwim/prms_0", "DeepSea/prms_0")
    settings, labels = _settings(sets=("continuous ergodic",), agents=("my_random_c",), n_steps=500_000,
                                 seeds=tuple(range(20)), only=only)
    batch = {"id": "b", "key": "k", "set_name": "continuous ergodic", "agent": "my_random_c",
             "members": [[m, s] for m in only for s in range(20)], "whole": None}
    (tmp_path / "plan.json").write_text(json.dumps({"settings": settings, "batches": [batch]}))
    with (tmp_path / "members.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(MEMBER_FIELDS)
        for m in only:
            for s in range(20):
                score = 0.5 + 0.001 * s
                w.writerow(["continuous ergodic", m, m.split("/")[0], "my_random_c", s, 500_000, score * 5e5,
                            score * 5e5, score, 1e5, 1e5, 0.9, "b"])
    report.write_report(tmp_path, "committed")
    md = (tmp_path / "report.md").read_text()
    header = _row(md, "continuous ergodic", "MDP")
    assert header[:5] == ["MDP", "my_random_c", "ucrl2 (committed)", "q_learning_continuous (committed)",
                          "random_continuous (committed)"]
    assert "ucrl2 (paper)" in header and "q_learning_continuous (paper)" in header
    row = _row(md, "continuous ergodic", "RiverSwim (1)")
    m, sd = _committed_cell("benchmark_continuous_full_20seeds", "continuous ergodic", "RiverSwim/prms_0", "ucrl2",
                            range(20))
    assert re.sub(r"\*", "", row[2]) == f"{m:.3f} ± {sd:.3f}"
    pm, psd = published.regret_table("continuous ergodic")["ucrl2"]["RiverSwim/prms_0"]
    assert row[header.index("ucrl2 (paper)")] == f"{pm:.2f} ± {psd:.2f}"
    m, sd = _committed_cell("benchmark_tabular_20seeds", "continuous ergodic", "RiverSwim/prms_0", "psrl_continuous",
                            range(20))
    assert re.sub(r"\*", "", row[header.index("psrl_continuous (committed)")]) == f"{m:.3f} ± {sd:.3f}"


@pytest.mark.slow
def test_a_run_folder_of_the_same_protocol_is_a_baseline_and_another_protocol_is_refused(registry, tmp_path):
    tiny = dict(sets=("episodic quick test",), seeds=(0, 1), n_steps=60, log_period=20, only=("RiverSwim",))
    shipped = tmp_path / "shipped"
    run.run_benchmark(run.RunConfig(**tiny, agents=("random_episodic", "q_learning_episodic")), shipped,
                      progress=False, report=False)
    registry.register(dataclasses.replace(agents.AGENTS["random_episodic"], name="my_random"))
    mine = tmp_path / "mine"
    with pytest.raises(ValueError, match="n_steps 60 here, 1000 there"):
        run.run_benchmark(run.RunConfig(**tiny, agents=("my_random",)), mine, progress=False, baseline="committed")
    run.run_benchmark(run.RunConfig(**tiny, agents=("my_random",)), mine, progress=False, baseline=shipped)
    md = (mine / "report.md").read_text()
    assert _row(md, "episodic quick test", "MDP") == ["MDP", "my_random", "random_episodic (shipped)",
                                                      "q_learning_episodic (shipped)", "seeds"]
    with (shipped / "members.csv").open(newline="") as f:
        theirs = [float(r["normalized_regret_per_step"]) for r in csv.DictReader(f) if r["agent"] == "q_learning_episodic"]
    row = _row(md, "episodic quick test", "RiverSwim (1)")
    assert re.sub(r"\*", "", row[3]) == f"{np.mean(theirs):.3f} ± {np.std(theirs, ddof=1):.3f}"
    with pytest.raises(ValueError, match="is the run's own folder"):
        report.write_report(mine, mine)
    longer = tmp_path / "longer"
    with pytest.raises(ValueError, match="n_steps 80 here, 60 there"):
        run.run_benchmark(run.RunConfig(**{**tiny, "n_steps": 80}, agents=("my_random",)), longer, progress=False,
                          baseline=shipped)


def test_the_package_data_holds_the_committed_run_folders_and_their_protocols(tmp_path):
    if not (TABLES / "benchmark_quick").exists():
        pytest.skip("needs the repository's docs/tables")
    n = baselines.write_committed(TABLES, tmp_path / "committed.csv")
    assert (tmp_path / "committed.csv").read_bytes() == baselines.COMMITTED_FILE.read_bytes(), (
        "hardness/benchmark/data/committed_members.csv is stale: run baselines.write_committed('docs/tables')")
    expected = 0
    for r in baselines.COMMITTED_RUNS:
        # The protocol recorded here is the one the folder's own report states and its members ran.
        header = (TABLES / r.folder / "report.md").read_text().splitlines()[2]
        periods = ", ".join(f"{r.period(s)} ({s})" for s in r.sets)
        assert header.startswith(f"{r.n_steps:,} steps per run, seeds {', '.join(map(str, r.seeds))}, "), r.folder
        assert all(f"{r.period(s)} ({s})" in header for s in r.sets), (r.folder, periods)
        assert f"hyperparameters: {r.hparams_source}, agent rules: paper" in header and "with the reference's" \
            not in header and "indicators: colosseum" not in header
        assert ("`StateInfo`" in header) == (r.emission == "state_info"), r.folder
        with (TABLES / r.folder / "members.csv").open(newline="") as f:
            rows = [x for x in csv.DictReader(f) if x["agent"] in r.agents and x["set"] in r.sets]
        assert {int(x["steps"]) for x in rows} == {r.n_steps} and {x["set"] for x in rows} == set(r.sets)
        assert sorted({int(x["seed"]) for x in rows}) == list(r.seeds)
        expected += len(rows)
    assert n == expected
    shipped = {a: e["values"] for a, e in sorted(hparams.load_tuned().items())}
    assert hashlib.sha256(json.dumps(shipped, sort_keys=True).encode()).hexdigest() == baselines.TUNED_DIGEST, (
        "the shipped tuned values changed: the committed tabular results are no longer the tuned agents'")


def test_tune_writes_to_its_output_folder_not_into_the_package(user_dir, monkeypatch):
    folder, module = user_dir
    from hardness.benchmark import search

    def fake_search(name, budget, *, n_buckets, progress, work_dir, run=None):
        space = search_spaces.search_space(name)
        values = [{f: lo for f, (lo, hi) in space.items()}, {f: hi for f, (lo, hi) in space.items()}]
        return search.SearchResult(name, ["sample_0", "sample_1"], values, np.array([[2.0], [1.0]]),
                                   [("RiverSwim/sample_0", 0)], [], 1.0, 0.5)

    monkeypatch.setattr(search, "search", fake_search)
    before = hparams.TUNED_FILE.read_bytes()
    parse = lambda argv: cli.build_parser().parse_args(["tune", *argv])  # noqa: E731
    assert parse([]).out == Path("results/tuning")
    cli.tune_command(parse(["--agents", f"{module}:EPSILON_GREEDY", "--steps", "10", "--quiet"]))
    path = folder / "results" / "tuning" / "tuned_hparams.json"
    data = json.loads(path.read_text())["agents"]
    assert data["epsilon_greedy_q"]["values"] == {"epsilon": 0.3, "learning_rate": 1.0}
    assert all(data[a] == e for a, e in hparams.load_tuned().items())  # a complete tuned file
    assert hparams.TUNED_FILE.read_bytes() == before
    assert float(hparams.hparams_for("epsilon_greedy_q", path).epsilon) == 0.3
    with pytest.raises(SystemExit, match="has no search space of ranges"):
        cli.tune_command(parse(["--agents", "random_episodic", "--quiet"]))
