"""hardness.analysis.sweep_cli, the command line of ``jaxmdp-sweep`` and ``jaxmdp-sweep-prand`` (hardness.cli.sweep).

End to end on a tiny grid (scenario 1, FrozenLake 3x3 episodic, p_rand 0 and 0.2, seeds 0, 1, 3 of 8, 9 and 7
states; the grid of tests/test_scenarios.py, so the two files share compiled programs): the table's raw measures
equal ``scenarios.compute`` of the whole grid, its normalised columns equal App. E over all rows (by hand), and
resuming, interrupting and chunking give the same table. The bookkeeping (resume with other seeds, scenario 4,
infinite values, the figure's axes) runs on a fake backend with known numbers, so it needs no compilation.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import shutil
import sys
import types
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

from hardness.analysis import scenarios, sweep_cli
from hardness.analysis.scenarios import MEASURES

from hardness_helpers import normalize_by_hand
from progress_run import run_with_progress

REPO = Path(__file__).resolve().parents[1]
SEEDS = (0, 1, 3)
VALUES = (0.0, 0.2)
ARGV = ["--family", "FrozenLake", "--param", "size=3", "--values", "0", "0.2", "--seed-list", "0", "1", "3",
        "--agent-steps", "0"]
STEM = "scenario1_FrozenLake_episodic"
# The CLI computes a seed at a time (a 1-seed slice of the padded grid); the reference is the whole grid in one
# vmapped call. Same operations per row; allow float32 round-off of a differently batched program.
RTOL = 1e-6


def run_main(scenario: int, argv: list[str], **kwargs) -> str:
    """``sweep_cli.main`` with its stdout captured (progress goes to stderr)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert sweep_cli.main(scenario, argv, **kwargs) == 0
    return out.getvalue()


def read_table(path: Path) -> list[dict]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def column(rows: list[dict], name: str) -> np.ndarray:
    return np.asarray([float(r[name]) for r in rows])


def measures_of(rows: list[dict]) -> np.ndarray:
    """``[n_rows, 3]`` raw measures."""
    return np.stack([column(rows, k) for k in MEASURES], axis=-1)


def check_normalized(rows: list[dict]) -> None:
    """The normalised columns are App. E over all rows of the table."""
    for k in MEASURES:
        want = normalize_by_hand(column(rows, k))
        got = column(rows, f"{k}_normalized")
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
        np.testing.assert_allclose(got, want, atol=1e-6)


@pytest.fixture(scope="module")
def reference():
    """The whole grid in one call of the library: ``[n_seeds, n_values, 3]`` measures and the n_states."""
    spec = scenarios.scenario_spec(1, "FrozenLake", episodic=True, seeds=SEEDS, values=VALUES, params=dict(size=3))
    raw = scenarios.compute(scenarios.prepare(spec))
    return spec, np.stack([raw[k] for k in MEASURES], axis=-1), raw["n_states"]


@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    """One real run, a seed per call, with the figure."""
    out = tmp_path_factory.mktemp("full")
    stdout = run_main(1, ARGV + ["--out", str(out)])
    return out, stdout


# ---------------------------------------------------------------------------------------------------------------
# End to end on the real backend
# ---------------------------------------------------------------------------------------------------------------


def test_full_run_table_equals_library(full_run, reference):
    out, stdout = full_run
    spec, want, n_states = reference
    csv_path = out / f"{STEM}.csv"
    assert stdout.split() == [str(csv_path), str(out / f"{STEM}.json"), str(out / f"{STEM}.png")]
    with csv_path.open(newline="") as f:
        assert next(csv.reader(f)) == sweep_cli.COLUMNS
    rows = read_table(csv_path)
    assert [(int(r["seed"]), float(r["value"])) for r in rows] == [(s, v) for s in SEEDS for v in VALUES]
    for r in rows:
        assert (r["scenario"], r["family"], r["setting"], r["variant"], r["parameter"]) == (
            "1", "FrozenLake", "episodic", "paper", "p_rand")
        assert all(r[f"{k}_converged"] == "True" for k in MEASURES)
    np.testing.assert_array_equal(column(rows, "n_states"), n_states.reshape(-1))
    np.testing.assert_array_equal(column(rows, "n_states"), [8, 8, 9, 9, 7, 7])
    np.testing.assert_allclose(measures_of(rows), want.reshape(-1, 3), rtol=RTOL)
    check_normalized(rows)
    config = json.loads((out / f"{STEM}.json").read_text())
    assert config == sweep_cli.config_of(spec)
    assert config["values"] == [0.0, 0.2] and config["gamma"] == 0.99 and config["parameter"] == "p_rand"
    assert config["params"] == {"make_reward_stochastic": "True", "p_frozen": "0.8", "size": "3"}
    assert not list(out.glob("*.tmp"))


def test_full_run_writes_a_png(full_run):
    out, _ = full_run
    img = matplotlib.image.imread(out / f"{STEM}.png")
    assert img.shape == (540, 750, 4)  # figsize 5 x 3.6 inches at 150 dpi, RGBA
    assert img[..., :3].std() > 0.05  # not blank


def test_resume_with_same_settings_recomputes_nothing(full_run, tmp_path, monkeypatch):
    out, _ = full_run
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    before = (tmp_path / f"{STEM}.csv").read_text()

    def forbidden(*args, **kwargs):
        raise AssertionError("a finished seed was recomputed")

    monkeypatch.setattr(scenarios, "prepare", forbidden)
    monkeypatch.setattr(scenarios, "compute", forbidden)
    run_main(1, ARGV + ["--out", str(tmp_path), "--resume", "--no-plot"])
    assert (tmp_path / f"{STEM}.csv").read_text() == before


@pytest.mark.parametrize(
    "extra",
    [["--gamma", "0.9"], ["--param", "p_frozen=0.9"], ["--values", "0", "0.3"]],
    ids=["gamma", "param", "values"],
)
def test_resume_with_other_settings_errors(full_run, tmp_path, capsys, extra):
    out, _ = full_run
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    before = (tmp_path / f"{STEM}.csv").read_text()
    with pytest.raises(SystemExit) as exc:
        sweep_cli.main(1, ARGV + ["--out", str(tmp_path), "--resume", "--no-plot"] + extra)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--resume" in err and "other settings" in err
    assert (tmp_path / f"{STEM}.csv").read_text() == before


def test_resume_without_settings_file_errors(full_run, tmp_path, capsys):
    out, _ = full_run
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    (tmp_path / f"{STEM}.json").unlink()
    with pytest.raises(SystemExit):
        sweep_cli.main(1, ARGV + ["--out", str(tmp_path), "--resume", "--no-plot"])
    assert "--resume" in capsys.readouterr().err


def test_interrupted_run_leaves_finished_seeds_and_resume_finishes(full_run, reference, tmp_path, monkeypatch):
    _, want, _ = reference
    real_compute = scenarios.compute
    calls: list[tuple[int, ...]] = []

    def interrupted(grid):
        calls.append(grid.seeds)
        if len(calls) == 2:
            raise KeyboardInterrupt  # what a user's Ctrl-C raises
        return real_compute(grid)

    monkeypatch.setattr(scenarios, "compute", interrupted)
    with pytest.raises(KeyboardInterrupt):
        sweep_cli.main(1, ARGV + ["--out", str(tmp_path), "--no-plot"])
    assert calls == [(0,), (1,)]
    csv_path = tmp_path / f"{STEM}.csv"
    rows = read_table(csv_path)  # a valid table of the finished seed, normalised over its rows
    assert [(int(r["seed"]), float(r["value"])) for r in rows] == [(0, 0.0), (0, 0.2)]
    np.testing.assert_allclose(measures_of(rows), want[0], rtol=RTOL)
    check_normalized(rows)
    assert not list(tmp_path.glob("*.tmp"))
    first = {k: [r[k] for r in rows] for k in MEASURES}

    calls.clear()
    monkeypatch.setattr(scenarios, "compute", lambda grid: calls.append(grid.seeds) or real_compute(grid))
    run_main(1, ARGV + ["--out", str(tmp_path), "--resume", "--no-plot"])
    assert calls == [(1,), (3,)]  # only the unfinished seeds
    rows = read_table(csv_path)
    assert [(int(r["seed"]), float(r["value"])) for r in rows] == [(s, v) for s in SEEDS for v in VALUES]
    assert {k: [r[k] for r in rows[:2]] for k in MEASURES} == first  # kept as written, not recomputed
    np.testing.assert_allclose(measures_of(rows), want.reshape(-1, 3), rtol=RTOL)
    check_normalized(rows)
    full_rows = read_table(full_run[0] / f"{STEM}.csv")
    np.testing.assert_allclose(measures_of(rows), measures_of(full_rows), rtol=RTOL)


def test_seeds_per_call_chunks_give_the_same_numbers(full_run, tmp_path, monkeypatch):
    real_compute = scenarios.compute
    calls = []
    monkeypatch.setattr(scenarios, "compute", lambda grid: calls.append(grid.seeds) or real_compute(grid))
    run_main(1, ARGV + ["--out", str(tmp_path), "--no-plot", "--seeds-per-call", "2"])
    assert calls == [(0, 1), (3, 3)]  # the short last chunk is filled with copies of its seed
    rows = read_table(tmp_path / f"{STEM}.csv")
    full_rows = read_table(full_run[0] / f"{STEM}.csv")
    assert [r["seed"] for r in rows] == [r["seed"] for r in full_rows]
    np.testing.assert_allclose(measures_of(rows), measures_of(full_rows), rtol=RTOL)
    for k in MEASURES:
        np.testing.assert_allclose(column(rows, f"{k}_normalized"), column(full_rows, f"{k}_normalized"), atol=1e-6)
    assert not (tmp_path / f"{STEM}.png").exists()


# ---------------------------------------------------------------------------------------------------------------
# Bookkeeping on a fake backend with known numbers
# ---------------------------------------------------------------------------------------------------------------


def fake_value(k: int, seed: int, j: int) -> float:
    """Measure ``k`` of ``(seed, value index j)``: exact binary fractions; the diameter of (seed 3, j 1) is +inf."""
    if k == 0 and seed == 3 and j == 1:
        return np.inf
    return 100.0 * k + 10.0 * seed + j + 0.125


class FakeGrid:
    def __init__(self, spec, seeds):
        self.spec, self.seeds = spec, tuple(seeds)
        V = len(spec.values)
        self.batch = types.SimpleNamespace(T=np.zeros((len(self.seeds) * V, 1)))
        self.n_states = np.asarray([[4 + s + 2 * j for j in range(V)] for s in self.seeds])

    def take(self, seeds):
        assert set(seeds) <= set(self.seeds)
        return FakeGrid(self.spec, seeds)


@pytest.fixture
def fake_backend(monkeypatch):
    """``scenarios.prepare`` / ``compute`` replaced by :class:`FakeGrid`; returns the seeds of every compute call."""
    calls: list[tuple[int, ...]] = []

    def compute(grid):
        calls.append(grid.seeds)
        V = len(grid.spec.values)
        out = {"n_states": grid.n_states.copy()}
        for k, name in enumerate(MEASURES):
            out[name] = np.asarray([[fake_value(k, s, j) for j in range(V)] for s in grid.seeds])
            out[name + "_converged"] = np.isfinite(out[name])
        return out

    monkeypatch.setattr(scenarios, "prepare", lambda spec, seeds=None: FakeGrid(spec, seeds or spec.seeds))
    monkeypatch.setattr(scenarios, "compute", compute)
    return calls


def fake_argv(out: Path, seeds=(0, 1, 3), *extra: str, plot: bool = False) -> list[str]:
    argv = ["--family", "RiverSwim", "--setting", "continuous", "--param", "size=5", "--values", "0", "0.1", "0.3",
            "--out", str(out), "--seed-list", *map(str, seeds), "--agent-steps", "0", *extra]
    return argv + ([] if plot else ["--no-plot"])


def test_fake_table_holds_the_backend_numbers_inf_and_nan(fake_backend, tmp_path):
    run_main(1, fake_argv(tmp_path))
    rows = read_table(tmp_path / "scenario1_RiverSwim_continuous.csv")
    assert len(rows) == 9 and fake_backend == [(0,), (1,), (3,)]
    for r in rows:
        seed, j = int(r["seed"]), (0.0, 0.1, 0.3).index(float(r["value"]))
        assert int(r["n_states"]) == 4 + seed + 2 * j
        for k, name in enumerate(MEASURES):
            assert float(r[name]) == fake_value(k, seed, j)
            assert r[f"{name}_converged"] == str(bool(np.isfinite(fake_value(k, seed, j))))
    assert rows[-2]["diameter"] == "inf" and rows[-2]["diameter_normalized"] == "nan"
    assert rows[-2]["diameter_converged"] == "False"
    check_normalized(rows)
    # diameter: finite min 0.125 (seed 0, j 0), max 32.125 (seed 3, j 2)
    assert float(rows[0]["diameter_normalized"]) == 0.0 and float(rows[-1]["diameter_normalized"]) == 1.0


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def test_progress_goes_to_the_stderr_of_the_moment(fake_backend, tmp_path, monkeypatch):
    """The bar (jaxmdp.experiment.progress) writes to sys.stderr as it is when the run starts, when that is a
    terminal: seeds done of the seeds to compute, time left."""
    term = Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    run_main(1, fake_argv(tmp_path))
    err = term.getvalue()
    assert "built 9 MDPs (4-11 states)" in err
    assert "scenario 1 RiverSwim continuous:   0%|" in err and "0/3 seeds [" in err
    assert err.rsplit("\r", 1)[-1].startswith("scenario 1 RiverSwim continuous: 100%|")
    assert "3/3 seeds [" in err and " left, " in err


def test_no_bar_when_stderr_is_not_a_terminal_or_quiet(fake_backend, tmp_path, capsys, monkeypatch):
    run_main(1, fake_argv(tmp_path))
    err = capsys.readouterr().err
    assert "built 9 MDPs (4-11 states)" in err and "seeds" not in err
    term = Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    run_main(1, fake_argv(tmp_path / "quiet", (0, 1, 3), "--quiet"))
    assert term.getvalue() == ""


def test_resume_keeps_finished_seeds_and_computes_new_ones(fake_backend, tmp_path):
    run_main(1, fake_argv(tmp_path, (0, 1)))
    csv_path = tmp_path / "scenario1_RiverSwim_continuous.csv"
    first = read_table(csv_path)
    fake_backend.clear()
    stdout = run_main(1, fake_argv(tmp_path, (3, 0, 1), "--resume"))
    assert fake_backend == [(3,)]
    rows = read_table(csv_path)
    assert [int(r["seed"]) for r in rows] == [3, 3, 3, 0, 0, 0, 1, 1, 1]  # the spec's seed order
    for old, new in zip(first, rows[3:]):
        assert {k: old[k] for k in MEASURES} == {k: new[k] for k in MEASURES}
    check_normalized(rows)
    assert str(csv_path) in stdout
    # A subset of the seeds: nothing to compute, the table holds exactly the seeds asked for.
    fake_backend.clear()
    run_main(1, fake_argv(tmp_path, (1,), "--resume"))
    assert fake_backend == []
    assert [int(r["seed"]) for r in read_table(csv_path)] == [1, 1, 1]


def test_resume_recomputes_a_partly_written_seed(fake_backend, tmp_path):
    run_main(1, fake_argv(tmp_path))
    csv_path = tmp_path / "scenario1_RiverSwim_continuous.csv"
    lines = csv_path.read_text().splitlines(keepends=True)
    csv_path.write_text("".join(lines[:-1]))  # drop the last row of seed 3
    fake_backend.clear()
    run_main(1, fake_argv(tmp_path, (0, 1, 3), "--resume"))
    assert fake_backend == [(3,)]
    assert len(read_table(csv_path)) == 9


def test_seeds_per_call_larger_than_the_seeds(fake_backend, tmp_path):
    run_main(1, fake_argv(tmp_path, (0, 1, 3), "--seeds-per-call", "5"))
    assert fake_backend == [(0, 1, 3, 0, 0)]
    assert len(read_table(tmp_path / "scenario1_RiverSwim_continuous.csv")) == 9


def test_size_script_scenario_4_and_figure_axes(fake_backend, tmp_path, monkeypatch):
    """--scenario 4: p_rand 0.1 in the settings, integer sizes; the figure's x axis is the mean
    number of states over seeds and its curves are the table's normalised measures."""
    seen = {}

    def fake_plot(x, curves, path, *, xlabel, title=""):
        seen.update(x=np.asarray(x), curves=curves, xlabel=xlabel, title=title)
        Path(path).write_bytes(b"")
        return Path(path)

    monkeypatch.setattr(sweep_cli, "plot_scenario", fake_plot)
    argv = ["--scenario", "4", "--family", "DeepSea", "--setting", "continuous", "--values", "3", "4",
            "--seed-list", "0", "3", "--out", str(tmp_path), "--agent-steps", "0"]
    run_main(3, argv, scenario_choices=(3, 4))
    stem = tmp_path / "scenario4_DeepSea_continuous"
    config = json.loads(stem.with_suffix(".json").read_text())
    assert config["scenario"] == 4 and config["parameter"] == "size" and config["values"] == [3, 4]
    assert config["params"]["p_rand"] == "0.1" and "size" not in config["params"]
    rows = read_table(stem.with_suffix(".csv"))
    assert [r["value"] for r in rows] == ["3", "4", "3", "4"]
    assert fake_backend == [(0,), (3,)]
    # n_states = 4 + seed + 2 j: seeds 0 and 3 -> [[4, 6], [7, 9]]
    np.testing.assert_array_equal(seen["x"], [5.5, 7.5])
    assert seen["xlabel"] == "n_states" and "Scenario 4: DeepSea continuous" in seen["title"]
    assert "p_rand=0.1" in seen["title"]
    for k, name in enumerate(MEASURES):
        raw = np.asarray([[fake_value(k, s, j) for j in range(2)] for s in (0, 3)])
        np.testing.assert_allclose(seen["curves"][name], normalize_by_hand(raw), atol=1e-6)
    # scenario 3 writes its own table
    run_main(3, argv[2:] + ["--no-plot"], scenario_choices=(3, 4))
    config3 = json.loads((tmp_path / "scenario3_DeepSea_continuous.json").read_text())
    assert config3["scenario"] == 3 and "p_rand" not in config3["params"]


def test_figure_of_a_noise_sweep_uses_the_values(fake_backend, tmp_path, monkeypatch):
    seen = {}
    monkeypatch.setattr(sweep_cli, "plot_scenario",
                        lambda x, curves, path, *, xlabel, title="": seen.update(x=np.asarray(x), xlabel=xlabel))
    run_main(2, fake_argv(tmp_path, (0, 1), plot=True))
    np.testing.assert_array_equal(seen["x"], [0.0, 0.1, 0.3])
    assert seen["xlabel"] == "p_lazy"


def test_colosseum_variant_gets_its_own_stem(fake_backend, tmp_path):
    run_main(1, fake_argv(tmp_path, (0,), "--variant", "colosseum", "--setting", "episodic"))
    assert (tmp_path / "scenario1_RiverSwim_episodic_colosseum.csv").exists()
    assert read_table(tmp_path / "scenario1_RiverSwim_episodic_colosseum.csv")[0]["variant"] == "colosseum"


# ---------------------------------------------------------------------------------------------------------------
# Arguments
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "scenario, argv, name",
    [
        (1, ["--seeds-per-call", "0"], "--seeds-per-call"),
        (1, ["--values", "0.2", "0.2"], "values"),
        (1, ["--values", "0.5", "1.2"], "values of p_rand"),
        (1, ["--values", "abc"], "--values"),
        (1, ["--gamma", "1.5"], "gamma"),
        (1, ["--gamma", "x"], "--gamma"),
        (1, ["--param", "size"], "--param"),
        (1, ["--param", "p_rand=0.1"], "p_rand"),
        (1, ["--param", "sise=3"], "sise"),
        (1, ["--family", "Nope"], "--family"),
        (1, ["--setting", "both"], "--setting"),
        (1, ["--variant", "reference"], "--variant"),
        (1, ["--seed-list", "0", "0"], "seeds"),
        (1, ["--seeds", "0"], "--seeds"),
        (1, ["--seeds", "-1"], "seeds"),
        (1, ["--seeds", "a"], "--seeds"),
        (1, ["--scenario", "4"], "--scenario"),
        (3, ["--scenario", "5"], "--scenario"),
        (3, ["--values", "0"], "values"),
        (3, ["--param", "size=4"], "size"),
        (2, ["--family", "DeepSea", "--param", "size=3", "--values", "0", "0.1"], "p_lazy"),
    ],
)
def test_bad_arguments_exit_naming_the_option(scenario, argv, name, tmp_path, capsys):
    base = ["--family", "RiverSwim", "--seed-list", "0", "--out", str(tmp_path / "o"), "--no-plot", "--agent-steps", "0"]
    if scenario in (1, 2):
        base += ["--param", "size=5", "--values", "0", "0.1"]
    else:
        base += ["--values", "4", "5"]
    with pytest.raises(SystemExit) as exc:
        sweep_cli.main(scenario, base + argv, scenario_choices=(3, 4) if scenario == 3 else None)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "error" in err and name in err
    assert not (tmp_path / "o").exists()  # nothing written


def test_parse_param_and_number():
    assert sweep_cli.parse_param("size=10") == ("size", 10)
    assert sweep_cli.parse_param(" p_rand = 0.1 ") == ("p_rand", 0.1)
    assert sweep_cli.parse_param("flag=True") == ("flag", True)
    assert sweep_cli.parse_param("p_lazy=None") == ("p_lazy", None)
    assert sweep_cli.parse_param("name=hello") == ("name", "hello")
    assert sweep_cli.parse_param("expr=a=b") == ("expr", "a=b")
    for bad in ("size", "=3", " =3"):
        with pytest.raises(Exception, match="key=value"):
            sweep_cli.parse_param(bad)
    assert sweep_cli.number("4") == 4 and type(sweep_cli.number("4")) is int
    assert sweep_cli.number("0.25") == 0.25 and sweep_cli.number("1e-1") == 0.1
    with pytest.raises(Exception, match="not a number"):
        sweep_cli.number("x")


# ---------------------------------------------------------------------------------------------------------------
# The script itself
# ---------------------------------------------------------------------------------------------------------------


def test_sweep_command_smoke(tmp_path):
    """``jaxmdp-sweep --scenario 3`` (``python -m hardness.cli.sweep``) in a fresh process: DeepSea continuous sizes 3 and 4. By hand, the diameter of a
    deterministic DeepSea of size n is 2n - 2 (from (0, 1) down, back to the start, down the diagonal)."""
    # The script's compilation cache goes to tmp_path, not the user's cache folder.
    env = dict(os.environ, PYTHONPATH=str(REPO), JAXMDP_COMPILATION_CACHE=str(tmp_path / "jax_cache"))
    cmd = [sys.executable, "-m", "hardness.cli.sweep", "--scenario", "3", "--family", "DeepSea", "--setting",
           "continuous", "--values", "3", "4", "--seeds", "1", "--no-plot", "--out", str(tmp_path),
           "--agent-steps", "0"]
    # A hang shows as a minute without CPU time or output (tests/progress_run.py); 600 s only bounds a spinning run.
    proc = run_with_progress(cmd, env=env, cwd=tmp_path, stall_s=60, limit_s=600)
    assert not proc.hung and not proc.over_limit, f"jaxmdp-sweep hung or ran over 600 s:\n{proc.stderr[-2000:]}"
    assert proc.returncode == 0, proc.stderr
    csv_path = tmp_path / "scenario3_DeepSea_continuous.csv"
    assert proc.stdout.split() == [str(csv_path), str(tmp_path / "scenario3_DeepSea_continuous.json")]
    assert "seeds" not in proc.stderr  # stderr is a pipe, not a terminal: no progress bar
    assert "of which compiling" in proc.stderr and f"cache {tmp_path / 'jax_cache'}: 0 hits" in proc.stderr
    rows = read_table(csv_path)
    assert [(r["seed"], r["value"], r["n_states"]) for r in rows] == [("0", "3", "6"), ("0", "4", "10")]
    np.testing.assert_allclose(column(rows, "diameter"), [4.0, 6.0], rtol=1e-6)
    assert all(r[f"{k}_converged"] == "True" for r in rows for k in MEASURES)
    check_normalized(rows)


# ---------------------------------------------------------------------------------------------------------------
# The tuned near-optimal agent's columns
# ---------------------------------------------------------------------------------------------------------------


@pytest.fixture
def fake_agent(monkeypatch):
    """``tuned_regret`` replaced by known regrets ``seed + 0.5 j`` (normalised) per MDP; records its calls."""
    calls = []

    def tuned_regret(mdps, eval_seeds, **kwargs):
        calls.append((list(eval_seeds), kwargs))
        n = len(eval_seeds)
        V = n // len(set(eval_seeds))
        norm = np.asarray([s + 0.5 * (i % V) for i, s in enumerate(eval_seeds)], np.float64)
        return types.SimpleNamespace(agent="ucrl2", cumulative_regret=4 * norm, normalized_cumulative_regret=norm)

    monkeypatch.setattr(sweep_cli, "tuned_regret", tuned_regret)
    monkeypatch.setattr(scenarios, "grid_mdps", lambda grid: None)
    return calls


def test_agent_columns_hold_the_tuned_regret_and_its_normalisation(fake_backend, fake_agent, tmp_path):
    argv = fake_argv(tmp_path, (0, 1))
    argv[argv.index("--agent-steps") + 1] = "300"
    run_main(1, argv + ["--agent-candidates", "3", "--agent-tuning-seeds", "2"])
    assert [c[0] for c in fake_agent] == [[0, 0, 0], [1, 1, 1]]  # one call per seed, one MDP per grid value
    assert fake_agent[0][1] == dict(n_steps=300, n_candidates=3, n_tuning_seeds=2)
    rows = read_table(tmp_path / "scenario1_RiverSwim_continuous.csv")
    norm = np.asarray([0, 0.5, 1.0, 1.0, 1.5, 2.0])
    assert all(r["agent"] == "ucrl2" for r in rows)
    np.testing.assert_allclose(column(rows, "agent_normalized_cumulative_regret"), norm)
    np.testing.assert_allclose(column(rows, "agent_cumulative_regret"), 4 * norm)
    np.testing.assert_allclose(column(rows, "agent_regret_normalized"), norm / 2.0, atol=1e-7)
    config = json.loads((tmp_path / "scenario1_RiverSwim_continuous.json").read_text())
    assert config["agent"] == dict(agent="ucrl2", steps=300, candidates=3, tuning_seeds=2)
    # resuming with the same agent settings recomputes nothing; with other settings it is refused
    run_main(1, argv + ["--agent-candidates", "3", "--agent-tuning-seeds", "2", "--resume"])
    assert len(fake_agent) == 2
    with pytest.raises(SystemExit):
        sweep_cli.main(1, argv + ["--agent-candidates", "4", "--agent-tuning-seeds", "2", "--resume"])


def test_agent_curve_reaches_the_figure(fake_backend, fake_agent, tmp_path, monkeypatch):
    seen = {}

    def fake_plot(x, curves, path, *, xlabel, title=""):
        seen.update(curves=curves, title=title)
        Path(path).write_bytes(b"")
        return Path(path)

    monkeypatch.setattr(sweep_cli, "plot_scenario", fake_plot)
    argv = fake_argv(tmp_path, (0, 1), plot=True)
    argv[argv.index("--agent-steps") + 1] = "100"
    run_main(1, argv)
    np.testing.assert_allclose(seen["curves"][sweep_cli.AGENT_CURVE], [[0, 0.25, 0.5], [0.5, 0.75, 1.0]], atol=1e-7)
    assert "tuned agent: ucrl2" in seen["title"]


@pytest.mark.parametrize(
    "extra, name",
    [(["--agent-steps", "-1"], "--agent-steps"), (["--agent-candidates", "0"], "--agent-candidates")],
)
def test_bad_agent_arguments(extra, name, tmp_path, capsys):
    with pytest.raises(SystemExit):
        sweep_cli.main(1, fake_argv(tmp_path) + extra)
    assert name in capsys.readouterr().err


def test_seeds_n_means_seeds_0_to_n_minus_1_and_the_default_is_three(fake_backend, tmp_path):
    argv = ["--family", "RiverSwim", "--setting", "continuous", "--param", "size=5", "--values", "0", "0.1", "0.3",
            "--out", str(tmp_path), "--agent-steps", "0", "--no-plot"]
    run_main(1, argv + ["--seeds", "2"])
    assert fake_backend == [(0,), (1,)]
    run_main(1, argv)
    assert fake_backend[2:] == [(0,), (1,), (2,)]
    assert [r["seed"] for r in read_table(tmp_path / "scenario1_RiverSwim_continuous.csv")][::3] == ["0", "1", "2"]


@pytest.mark.parametrize("scenario, folder", [(None, "sweep_prand"), ("2", "sweep_plazy"), ("4", "sweep_size")])
def test_the_sweep_command_takes_the_scenario_and_its_default_folder(scenario, folder, fake_backend, tmp_path,
                                                                     monkeypatch, capsys):
    from hardness.cli import sweep

    monkeypatch.chdir(tmp_path)
    values = ["--values", "3", "4"] if scenario == "4" else ["--values", "0", "0.1"]
    argv = ["--family", "RiverSwim", "--setting", "continuous", "--seeds", "1", "--agent-steps", "0", "--no-plot",
            "--no-compile-cache", "--quiet", *values] + ([] if scenario else ["--param", "size=5"])
    if scenario == "4":
        argv += ["--param", "p_lazy=0.1"]
    elif scenario == "2":
        argv += ["--param", "size=5"]
    assert sweep.main((["--scenario", scenario] if scenario else []) + argv) == 0
    k = scenario or "1"
    assert (tmp_path / "results" / folder / f"scenario{k}_RiverSwim_continuous.csv").exists()
    err = capsys.readouterr().err
    assert "of which compiling" in err and "no cache" in err
    assert "seeds" not in err  # --quiet: no progress bar
    if scenario is None:
        assert sweep.main_prand(argv) == 0
        with pytest.raises(SystemExit):
            sweep.main_prand(["--scenario", "2", *argv])  # the alias has no --scenario
