"""Run a subprocess and tell a hang from slowness by progress, not by a tight wall-clock limit.

A process makes progress while its CPU time (user + system over all its threads, from ``/proc/<pid>/stat``) grows or
its output grows. A deadlocked thread pool waits: neither grows. On a loaded machine a slow process still gets CPU
ticks every few seconds, so ``stall_s`` seconds without either is a hang whatever the load (checked: the solve
deadlock of tests/test_linalg.py's program, with ``vmap(jnp.linalg.solve)``, was called hung 28 s after its start at
``stall_s=20``). Not counted: the CPU time of the process's own children, so a command that waits silently on a
subprocess would look hung. Without ``/proc`` (not Linux) CPU time cannot be read and silence alone is not called a
hang. ``limit_s`` is only an outer bound against a process that spins forever.
"""

from __future__ import annotations

import os
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Finished:
    returncode: int | None  # None when the run was stopped (hung or over the outer bound)
    stdout: str
    stderr: str
    hung: bool  # no CPU time and no output for ``stall_s`` seconds (never without /proc)
    over_limit: bool  # still progressing after ``limit_s`` seconds


def cpu_ticks(pid: int) -> int | None:
    """utime + stime of ``pid`` in clock ticks (its threads included), or ``None`` without ``/proc``."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return int(fields[11]) + int(fields[12])  # fields 14 and 15 of proc(5), counted after the ")"


def run_with_progress(cmd: list[str], *, env: dict, cwd, stall_s: float = 60.0, limit_s: float = 900.0,
                      poll_s: float = 0.5) -> Finished:
    """Run ``cmd``; stop it when it made no progress for ``stall_s`` seconds or ran ``limit_s`` seconds."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=out, stderr=err)
        start = last_progress = time.monotonic()
        last = (cpu_ticks(proc.pid), 0)
        hung = over = False
        try:
            while proc.poll() is None:
                time.sleep(poll_s)
                now = time.monotonic()
                seen = (cpu_ticks(proc.pid), os.fstat(out.fileno()).st_size + os.fstat(err.fileno()).st_size)
                if seen != last:
                    last, last_progress = seen, now
                elif now - last_progress > stall_s and last[0] is not None:
                    hung = True
                    break
                if now - start > limit_s:
                    over = True
                    break
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        out.seek(0)
        err.seek(0)
        return Finished(None if hung or over else proc.returncode, out.read().decode(errors="replace"),
                        err.read().decode(errors="replace"), hung, over)


def run_on_host_devices(script: str, n_devices: int = 2, **kwargs) -> dict:
    """Run ``python -c script`` with ``n_devices`` fake host devices (``XLA_FLAGS``) and the project and tests on its
    path, watched by :func:`run_with_progress` (``kwargs``); it must succeed and print a JSON object as its last line,
    which is returned."""
    import json
    import sys

    tests = Path(__file__).resolve().parent
    env = dict(os.environ)
    flag = f"--xla_force_host_platform_device_count={n_devices}"
    env["XLA_FLAGS"] = (env.get("XLA_FLAGS", "") + " " + flag).strip()
    env["PYTHONPATH"] = os.pathsep.join([str(tests.parent), str(tests), env.get("PYTHONPATH", "")])
    run = run_with_progress([sys.executable, "-c", script], env=env, cwd=tests.parent, **kwargs)
    assert not run.hung and not run.over_limit, f"hung={run.hung} over_limit={run.over_limit}: {run.stderr[-3000:]}"
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout.strip().splitlines()[-1])
