"""hardness.analysis.deep_regret (run by ``jaxmdp-regret-table --deep``) on a tiny configuration: DQN and the random
agent on one small RiverSwim BlockMDP, 2 seeds, 300 steps. The table's rows and columns are the runner's numbers,
rows are appended as pairs finish, and an invocation skips the finished pairs."""

from __future__ import annotations

import csv

import numpy as np
import pytest

import agents
import jaxmdp
from hardness.analysis import deep_regret
from jaxmdp.experiment import runner

# Nightly: the deep table's command; by default, test_regret_table.py runs the tabular one and the runner's tests the
# deep agents.
pytestmark = pytest.mark.nightly

STEPS, SEEDS = 300, 2
ARGS = ["--steps", str(STEPS), "--seeds", str(SEEDS), "--instances", "RiverSwim-3-continuous",
        "--agents", "dqn_continuous", "random_continuous", "--log-period", "50", "--quiet"]


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    out = tmp_path_factory.mktemp("deep_regret")
    return out, deep_regret.main(ARGS + ["--out", str(out)])


def test_rows_are_the_runner_numbers(table):
    out, res = table
    assert res["ran"] == [("RiverSwim-3-continuous", "dqn_continuous"), ("RiverSwim-3-continuous",
                                                                          "random_continuous")]
    with (out / "rows.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(deep_regret.ROW_FIELDS) and len(rows) == 2
    by_agent = {r["agent"]: r for r in rows}
    # The random agent ignores its observations: an independent run on the plain MDP gives the same final regret.
    inst = deep_regret.parse_instance("RiverSwim-3-continuous")
    plain = inst.build().mdp
    rnd = agents.get("random_continuous")
    ref = runner.run(rnd, runner.product([plain], [rnd.default_hparams], range(SEEDS)), STEPS, log_period=50)
    expected = ref.column("normalized_cumulative_regret")[-1] / STEPS
    r = by_agent["random_continuous"]
    np.testing.assert_allclose([float(x) for x in r["per_seed"].split()], expected, rtol=1e-5)
    assert float(r["regret_per_step_mean"]) == pytest.approx(expected.mean(), rel=1e-5)
    assert float(r["regret_per_step_std"]) == pytest.approx(np.std(expected, ddof=1), rel=1e-4, abs=1e-9)
    baseline = ref.column("random_normalized_cumulative_regret")[-1][0] / STEPS
    for r in rows:
        assert int(r["n_steps"]) == STEPS and int(r["n_seeds"]) == SEEDS and r["setting"] == "continuous"
        assert float(r["random_baseline"]) == pytest.approx(baseline, rel=1e-6)
        assert float(r["agent_steps_per_s"]) > 0
    assert not list((out / "runs").glob("*.npz"))  # checkpoints removed once a row is written
    assert len(list((out / "runs").glob("*.csv"))) == 2


def test_markdown_table(table):
    out, res = table
    md = (out / "deep_agents_regret.md").read_text()
    lines = [line for line in md.splitlines() if line.startswith("| ")]
    assert lines[0] == "| instance | agent | regret / step | per seed | below random | agent-steps/s | compile s |"
    cells = [line.strip("| ").split(" | ") for line in lines[1:]]
    assert [c[:2] for c in cells] == [["RiverSwim-3-continuous", "dqn_continuous"],
                                      ["RiverSwim-3-continuous", "random_continuous"],
                                      ["RiverSwim-3-continuous", "*uniform policy (exact)*"]]
    dqn, rnd = (r for r in res["rows"])
    assert cells[0][2] == f"{float(dqn['regret_per_step_mean']):.3f} ± {float(dqn['regret_per_step_std']):.3f}"
    assert cells[0][4] == deep_regret.verdict(dqn, rnd) != "" and cells[1][4] == ""
    assert "Made by `jaxmdp-regret-table --deep --steps 300" in md
    # The agents of the instance's setting that were not run are listed as missing.
    assert ("Not run yet: RiverSwim-3-continuous / boot_dqn_continuous, RiverSwim-3-continuous / "
            "actor_critic_continuous, RiverSwim-3-continuous / actor_critic_rnn_continuous.") in md


def test_resume_skips_finished_pairs(table, monkeypatch):
    out, res = table
    again = deep_regret.main(ARGS + ["--out", str(out)])
    assert again["ran"] == [] and again["rows"] == res["rows"]
    # Drop the random agent's row: only that pair runs again, and gives the same numbers (same seeds, same keys).
    path = out / "rows.csv"
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(line for line in lines if "random_continuous" not in line))
    calls = []
    real = deep_regret.run_pair
    monkeypatch.setattr(deep_regret, "run_pair", lambda inst, name, *a, **k: calls.append(name) or real(
        inst, name, *a, **k))
    third = deep_regret.main(ARGS + ["--out", str(out)])
    assert calls == ["random_continuous"]
    assert [r["per_seed"] for r in third["rows"]] == [r["per_seed"] for r in res["rows"]]


def test_verdicts_and_bad_input():
    row = lambda agent, xs: dict(agent=agent, per_seed=" ".join(map(str, xs)))  # noqa: E731
    rnd = row("random_episodic", [0.5, 0.6])
    assert deep_regret.verdict(row("dqn_episodic", [0.1, 0.4]), rnd) == "yes, every seed"
    assert deep_regret.verdict(row("dqn_episodic", [0.1, 0.55]), rnd) == "yes"
    assert deep_regret.verdict(row("dqn_episodic", [0.5, 0.7]), rnd) == "**no**"
    assert deep_regret.verdict(rnd, rnd) == ""
    assert deep_regret.agents_of(True) == ["dqn_episodic", "boot_dqn_episodic", "actor_critic_episodic",
                                           "actor_critic_rnn_episodic", "random_episodic"]
    with pytest.raises(ValueError, match="Family-size-setting"):
        deep_regret.parse_instance("RiverSwim-6")
    with pytest.raises(SystemExit, match="unknown agent 'dqn'"):
        deep_regret.main(["--agents", "dqn"])
    block = deep_regret.parse_instance("DeepSea-4-episodic").build()
    assert isinstance(block, jaxmdp.BlockMDP) and block.emission_kind == "state_info" and block.episodic


def test_the_regret_table_command_with_deep_runs_this_table(table, monkeypatch, capsys):
    # Every pair is finished: the command reruns nothing, rewrites the table naming itself, and reports compile time.
    from hardness.cli import regret_table as cli

    out, _ = table
    monkeypatch.setenv("XLA_FLAGS", "")  # the command asks for one host device per core; restored afterwards
    monkeypatch.setattr(deep_regret, "run_pair", lambda *a, **kw: pytest.fail("a finished pair ran again"))
    assert cli.main(["--deep", *ARGS, "--out", str(out), "--no-compile-cache"]) == 0
    assert "Made by `jaxmdp-regret-table --deep --steps 300" in (out / "deep_agents_regret.md").read_text()
    assert "of which compiling" in capsys.readouterr().err
    assert "--instances" in cli.build_parser(deep=True).format_help()
    assert "--families" in cli.build_parser().format_help()
