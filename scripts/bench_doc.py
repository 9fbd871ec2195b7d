"""Helpers shared by the benchmark scripts: appending a dated section to a benchmark's Markdown file
(docs/benchmarks/), for the scripts that keep a history of their runs there rather than rewriting the file, and the
best-of-``n`` wall time of a call or of several calls taken in turn."""

from __future__ import annotations

import os
import platform
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import jax


def append_section(doc: str | Path, title: str, argv: Sequence[str] | None, body: Sequence[str]) -> None:
    """Append to ``doc`` (created with the heading ``title``) a section headed by the date, device and machine, the
    command that made it (``argv``: the script's arguments, ``None`` for ``sys.argv``), the load average (the
    machine is shared: ratios hold under load, absolute numbers do not) and ``body``'s lines."""
    device = jax.devices()[0]
    script = Path(sys.argv[0]).name
    args = sys.argv[1:] if argv is None else list(argv)
    text = "\n".join([
        f"## {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {device.platform} ({device.device_kind}), "
        f"{platform.machine()}",
        "",
        "    " + " ".join(["python", f"scripts/{script}", *args]),
        "",
        f"Load average at the end: {os.getloadavg()[0]:.1f} ({os.cpu_count()} cores): the ratios hold under load, "
        "the absolute numbers do not.",
        "",
        *body,
        "",
    ])
    doc = Path(doc)
    old = doc.read_text() if doc.exists() else f"# {title}\n"
    doc.write_text(old.rstrip("\n") + "\n\n" + text)


def best_seconds(fn: Callable[[], object], repeats: int) -> float:
    """The shortest wall time of ``repeats`` calls of ``fn`` (results waited for), after one call that compiles."""
    jax.block_until_ready(fn())
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - start)
    return min(times)


def interleaved_best(fns: dict[str, Callable[..., object]], args: Sequence[object], repeats: int) -> dict[str, float]:
    """The shortest wall time of each of ``fns`` on ``args`` over ``repeats`` rounds that call them in turn (results
    waited for), after one call each that compiles: a machine's slow spell then falls on all of them alike."""
    for fn in fns.values():
        jax.block_until_ready(fn(*args))
    best = dict.fromkeys(fns, float("inf"))
    for _ in range(repeats):
        for name, fn in fns.items():
            start = time.perf_counter()
            jax.block_until_ready(fn(*args))
            best[name] = min(best[name], time.perf_counter() - start)
    return best

