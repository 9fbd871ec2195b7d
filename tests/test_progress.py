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


def test_log_lines_when_asked(monkeypatch):
    """In a log (not a terminal) with ``log_every``: plain lines, at most one per interval at the first update past
    it and one at the end, the compilations' seconds taken off the running time that the rate and the time left
    count; numbers worked out by hand."""
    clock = Clock()
    monkeypatch.setattr("jaxmdp.experiment.progress._now", clock)
    log = io.StringIO()
    bar = Progress(1000, "benchmark", file=log, log_every=60)
    assert bar.enabled
    bar.skip(200)  # 800 to run here
    with bar.compiling("the chunk program"):
        clock.now += 100.0
    clock.now += 30.0
    bar.update(100)  # 130 s since the start: a line; 30 s of running for 100 units
    clock.now += 30.0
    bar.update(100)  # 30 s since the last line: none
    bar.set_postfix("b1: 35 members")
    clock.now += 30.0
    bar.update(100)
    bar.write("kept in logs", log=True)
    bar.write("a line for the terminal only")
    clock.now += 30.0
    bar.update(100)
    bar.close()  # the last state, not shown yet
    assert log.getvalue().splitlines() == [
        "compiling the chunk program ... 100.0 s",
        "benchmark:  12% 100/800 member-steps [02:10 elapsed, 03:30 left, 3.33 member-steps/s]",
        "benchmark:  38% 300/800 member-steps [03:10 elapsed, 02:30 left, 3.33 member-steps/s, b1: 35 members]",
        "kept in logs",
        "benchmark:  50% 400/800 member-steps [03:40 elapsed, 02:00 left, 3.33 member-steps/s, b1: 35 members]",
    ]
    # Closing right after a line adds none; nothing ran, nothing shown; quiet wins; a terminal keeps its bar.
    log = io.StringIO()
    bar = Progress(10, "run", "seeds", file=log, unit_scale=False, log_every=1)
    clock.now += 2.0
    bar.update(10)
    bar.close()
    assert log.getvalue() == "run: 100% 10/10 seeds [00:02 elapsed, 00:00 left, 5 seeds/s]\n"
    for stream, quiet in ((io.StringIO(), False), (io.StringIO(), True)):
        drive(Progress(100, "run", file=stream, quiet=quiet, log_every=1e-9))
        assert stream.getvalue() == ("" if quiet else "compiling the chunk program ... 0.0 s\n"
                                     "run:  56% 50.0/90.0 member-steps [00:00 elapsed, ? left, ? member-steps/s, x]\n")
    term = Terminal()
    drive(Progress(100, "run", file=term, mininterval=0, log_every=1))
    assert "\r" in term.getvalue()


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
    ({"total": 10, "log_every": 0}, "log_every must be a positive number of seconds or None"),
    ({"total": 10, "log_every": float("inf")}, "log_every must be a positive number of seconds or None"),
    ({"total": 10, "log_every": True}, "log_every must be a positive number of seconds or None"),
    ({"total": 10, "log_every": "60"}, "log_every must be a positive number of seconds or None"),
])
def test_bad_input(kw, match):
    with pytest.raises(ValueError, match=re.escape(match)):
        Progress(**kw)
