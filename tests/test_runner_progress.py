"""The runner's progress display (``runner.run(progress=...)``, :mod:`jaxmdp.experiment.progress`): what it shows on a
terminal, that it writes nothing elsewhere, that a caller's display counts member-steps across runs and chunk by
chunk, and that the results are the same bit for bit with and without it.

One shape throughout (Q-learning on RiverSwim size 5, 2 seeds, 1200 steps in chunks of 300), so the programs
compile once.
"""

from __future__ import annotations

import io
import sys

import jax
import numpy as np
import pytest

import agents
import jaxmdp
from jaxmdp.experiment import runner
from jaxmdp.experiment.progress import Progress

N_STEPS, CHUNK, MEMBERS = 1200, 300, 2
PROGRAMS = ("the indicator constants", "the initialisation program", "the chunk program")


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


@pytest.fixture(scope="module")
def setup():
    agent = agents.get("q_learning_continuous")
    mdp = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, randomize_actions=False, p_lazy=0.1,
                      make_reward_stochastic=True)
    return agent, runner.product([mdp], [agent.default_hparams], seeds=range(MEMBERS))


def run(setup, **kw) -> runner.RunResult:
    agent, g = setup
    return runner.run(agent, g, N_STEPS, n_records=8, chunk_steps=CHUNK, **kw)


@pytest.fixture(scope="module")
def quiet_result(setup):
    return run(setup)


def assert_same_results(a: runner.RunResult, b: runner.RunResult) -> None:
    np.testing.assert_array_equal(a.steps, b.steps)
    np.testing.assert_array_equal(a.values, b.values)
    jax.tree.map(np.testing.assert_array_equal, a.agent_state, b.agent_state)


def test_progress_on_a_terminal_shows_rate_time_left_and_compilations(setup, quiet_result, monkeypatch):
    term = Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    result = run(setup, progress=True)
    assert_same_results(result, quiet_result)
    text = term.getvalue()
    lines = text.replace("\r", "\n").splitlines()
    for program in PROGRAMS:  # announced while compiling, then its seconds on a line of its own
        assert f"q_learning_continuous, 2 members, compiling {program} ...:" in text
        assert any(line.startswith(f"compiling {program} ... ") and line.endswith(" s") for line in lines)
    last = text.rsplit("\r", 1)[-1]
    assert last.startswith("q_learning_continuous, 2 members: 100%|")
    assert "2.40k/2.40k member-steps [" in last and " left, " in last and "member-steps/s]" in last
    assert "? member-steps/s" not in last  # a rate was measured
    assert text.endswith("\n")  # the runner closed its own display


def test_a_callers_display_counts_member_steps_chunk_by_chunk_across_runs(setup, quiet_result):
    term = Terminal()
    with Progress(2 * MEMBERS * N_STEPS, "benchmark", file=term, mininterval=0) as bar:
        first = run(setup, progress=bar)
        second = run(setup, progress=bar)
        assert bar.enabled and bar._bar.n == 2 * MEMBERS * N_STEPS and not bar._bar.disable  # the runs left it open
    assert_same_results(first, quiet_result)
    assert_same_results(second, quiet_result)
    shown = [part.split(" member-steps")[0].split("| ")[-1] for part in term.getvalue().split("\r")
             if part.startswith("benchmark:")]
    # Each chunk advances the bar by its 300 steps of 2 members, through both runs.
    for done in ("600", "1.20k", "1.80k", "2.40k", "3.00k", "3.60k", "4.20k", "4.80k"):
        assert f"{done}/4.80k" in shown


def test_a_resumed_run_takes_its_finished_steps_off_the_total(setup, quiet_result, tmp_path):
    ckpt = tmp_path / "run.npz"
    part = run(setup, checkpoint_path=ckpt, stop_after_chunks=2)
    assert part.steps[-1] == 2 * CHUNK
    term = Terminal()
    with Progress(MEMBERS * N_STEPS, "benchmark", file=term, mininterval=0) as bar:
        rest = run(setup, checkpoint_path=ckpt, progress=bar)
    assert_same_results(rest, quiet_result)
    text = term.getvalue()
    assert f"resuming q_learning_continuous at step {2 * CHUNK} of {N_STEPS} ({ckpt})\n" in text
    assert "600/1.20k member-steps" in text and text.rsplit("\r", 1)[-1].startswith("benchmark: 100%|")
    assert "1.20k/1.20k member-steps" in text


def test_progress_writes_nothing_when_stderr_is_not_a_terminal(setup, quiet_result, monkeypatch):
    pipe = io.StringIO()
    monkeypatch.setattr(sys, "stderr", pipe)
    assert_same_results(run(setup, progress=True), quiet_result)
    assert pipe.getvalue() == ""


def test_a_bad_progress_is_refused(setup):
    with pytest.raises(ValueError, match="progress must be True, False or a jaxmdp.experiment.progress.Progress"):
        run(setup, progress="yes")
