"""jaxmdp.experiment.progress, the one progress display of long runs (the runner, the benchmark, the sweeps).

The display is driven by a fake clock (tqdm reads ``tqdm.std.time``), so the rate and the time left are checked
against numbers worked out by hand, with no timing; a terminal is a StringIO whose ``isatty()`` is True.
"""

from __future__ import annotations

import io
import re
import sys

import pytest

from jaxmdp.experiment.progress import Progress, is_terminal


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


class Clock:
    """A fake wall clock for tqdm (its bars read ``tqdm.std.time`` when they are made)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch):
    c = Clock()
    monkeypatch.setattr("tqdm.std.time", c)
    return c


def last_line(text: str) -> str:
    """What the terminal shows last: the text after the last carriage return."""
    return text.rsplit("\r", 1)[-1]


def test_rate_and_time_left_count_running_after_the_compilation(clock):
    term = Terminal()
    with Progress(1000, "psrl, 2 members", file=term, mininterval=0) as bar:
        with bar.compiling("the chunk program"):
            assert "psrl, 2 members, compiling the chunk program ...:   0%" in term.getvalue()  # shown meanwhile
            clock.now += 100.0
        # The finished compilation stays as a line of its own, with its seconds.
        assert "\ncompiling the chunk program ... 100.0 s\n" in "\n" + term.getvalue().replace("\r", "\n")
        clock.now += 10.0
        bar.update(250)
        clock.now += 10.0
        bar.update(250)
        shown = last_line(term.getvalue())
    # 250 member-steps per 10 s in both intervals (the 100 s of compiling excluded): 25 per second, so the 500 left
    # take 20 s; the elapsed time is the wall time, compilation included (120 s).
    assert shown.startswith("psrl, 2 members:  50%|")
    assert "500/1.00k member-steps [02:00 elapsed, 00:20 left, 25.0 member-steps/s]" in shown
    assert term.getvalue().endswith("\n")  # closed: the last line stays


def test_skipped_work_leaves_the_total(clock):
    """A resumed run's finished steps are taken off the total: the time left counts what this call runs."""
    term = Terminal()
    bar = Progress(1000, "run", file=term, mininterval=0)
    bar.skip(400)
    clock.now += 30.0
    bar.update(300)
    shown = last_line(term.getvalue())
    bar.close()
    assert "300/600 member-steps [00:30 elapsed, 00:30 left, 10.0 member-steps/s]" in shown


def test_other_units_and_postfix(clock):
    term = Terminal()
    with Progress(3, "scenario 1", "seeds", file=term, unit_scale=False, mininterval=0) as bar:
        bar.set_postfix("seed 2")
        clock.now += 4.0
        bar.update(1)
        bar.write("a line above the bar")
        shown = last_line(term.getvalue())
    assert "1/3 seeds [00:04 elapsed, 00:08 left,  0.25 seeds/s, seed 2]" in shown
    assert "a line above the bar\n" in term.getvalue()


def drive(bar: Progress) -> None:
    with bar.compiling("the chunk program"):
        pass
    bar.set_postfix("x")
    bar.skip(10)
    bar.update(50)
    bar.write("a line")
    bar.close()


def test_not_a_terminal_or_quiet_writes_nothing():
    pipe = io.StringIO()
    bar = Progress(100, "run", file=pipe, mininterval=0)
    assert not bar.enabled
    drive(bar)
    assert pipe.getvalue() == ""
    term = Terminal()
    bar = Progress(100, "run", file=term, quiet=True, mininterval=0)
    assert not bar.enabled
    drive(bar)
    assert term.getvalue() == ""
    for stream, quiet in ((io.StringIO(), False), (Terminal(), True)):
        bar = Progress(100, "run", file=stream, quiet=quiet)
        bar.write("kept in logs", log=True)
        assert stream.getvalue() == ("" if quiet else "kept in logs\n")  # a message for logs: never when quiet
    shown = Terminal()
    bar = Progress(100, "run", file=shown, mininterval=0)
    assert bar.enabled
    drive(bar)
    assert "50.0/90.0 member-steps" in shown.getvalue()  # the same calls on a terminal do show


def test_default_stream_is_the_stderr_of_the_moment(monkeypatch):
    term = Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    with Progress(10, "run"):
        pass
    assert "0.00/10.0 member-steps" in term.getvalue()


def test_is_terminal(tmp_path):
    closed = open(tmp_path / "log", "w")  # noqa: SIM115
    closed.close()  # isatty() of a closed file raises ValueError
    assert is_terminal(Terminal()) and not is_terminal(io.StringIO()) and not is_terminal(object())
    assert not is_terminal(closed)


@pytest.mark.parametrize("kw, match", [
    ({"total": -1}, "total must be an integer >= 0"),
    ({"total": 2.5}, "total must be an integer >= 0"),
    ({"total": 10, "quiet": "yes"}, "quiet must be True or False"),
])
def test_bad_input(kw, match):
    with pytest.raises(ValueError, match=re.escape(match)):
        Progress(**kw)
