"""tests/progress_run.py: a process that waits without output is a hang; one that computes or prints is not."""

from __future__ import annotations

import os
import sys

import progress_run
from progress_run import run_with_progress


def test_a_silent_idle_process_is_a_hang():
    done = run_with_progress([sys.executable, "-c", "import time; time.sleep(30)"], env=dict(os.environ), cwd=".",
                             stall_s=2.0, limit_s=25.0, poll_s=0.1)
    assert done.hung and not done.over_limit and done.returncode is None


def test_a_printing_idle_process_is_not_a_hang():
    program = "import time\nfor i in range(8):\n    print(i, flush=True); time.sleep(0.5)"
    done = run_with_progress([sys.executable, "-c", program], env=dict(os.environ), cwd=".", stall_s=2.0,
                             limit_s=25.0, poll_s=0.1)
    assert not done.hung and done.returncode == 0 and done.stdout.split() == [str(i) for i in range(8)]


def test_a_computing_silent_process_is_not_a_hang_but_the_outer_bound_stops_it():
    done = run_with_progress([sys.executable, "-c", "while True: pass"], env=dict(os.environ), cwd=".",
                             stall_s=2.0, limit_s=4.0, poll_s=0.1)
    assert done.over_limit and not done.hung and done.returncode is None


def test_without_cpu_readings_silence_alone_is_not_a_hang(monkeypatch):
    # No /proc (not Linux): a silent process may be compiling, so only the outer bound stops it.
    monkeypatch.setattr(progress_run, "cpu_ticks", lambda pid: None)
    done = run_with_progress([sys.executable, "-c", "import time; time.sleep(30)"], env=dict(os.environ), cwd=".",
                             stall_s=1.0, limit_s=3.0, poll_s=0.1)
    assert done.over_limit and not done.hung and done.returncode is None
