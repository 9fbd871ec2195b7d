"""What the standing benchmarks share: their common options, the machine and commit they ran on, writing their one
table to ``results/benchmarks/<name>.md`` and (``--update-docs``) into its section of ``docs/performance.md``, and the
best-of-``n`` wall time of a call or of several calls taken in turn, and a tabular agent's state after random play.

A benchmark's section of ``docs/performance.md`` lies between the markers ``<!-- bench:<name> -->`` and
``<!-- /bench:<name> -->`` (``<name>``: the benchmark file's stem); ``--update-docs`` replaces what is between them and
nothing else.
"""

from __future__ import annotations

import argparse
import os
import platform
import shlex
import subprocess
import time
from collections.abc import Callable, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "benchmarks"
DOCS = ROOT / "docs" / "performance.md"


def add_common_args(parser: argparse.ArgumentParser) -> None:
    """``--smoke``, ``--update-docs``, ``--out``, ``--docs`` and ``--no-compile-cache``."""
    from jaxmdp.experiment import compilation

    parser.add_argument("--smoke", action="store_true", help="a tiny size, to check that the benchmark runs")
    parser.add_argument("--update-docs", action="store_true",
                        help="replace this benchmark's section of docs/performance.md with the table")
    parser.add_argument("--out", type=Path, default=RESULTS, help="folder of the Markdown table (%(default)s)")
    parser.add_argument("--docs", type=Path, default=DOCS, help="the page --update-docs edits (%(default)s)")
    compilation.add_cache_flag(parser)


def commit() -> str:
    """The repository's commit (``+dirty`` when the work tree differs from it), or ``unknown``."""
    try:
        sha = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                             check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return sha + ("+dirty" if dirty else "")


def cpu_name() -> str:
    """The CPU's model name (``/proc/cpuinfo``; else :func:`platform.processor`)."""
    try:
        with open("/proc/cpuinfo") as f:
            return next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def machine() -> str:
    """Platform, CPU and cores, JAX's version, backend and first device."""
    import jax

    device = jax.devices()[0]
    return (f"{platform.system()} {platform.machine()}, {cpu_name()}, {os.cpu_count()} cores; jax {jax.__version__}, "
            f"{device.platform} ({device.device_kind}), {jax.local_device_count()} device(s)")


def command(name: str, argv: Sequence[str]) -> str:
    """The command line that made a table: ``python benchmarks/<name>.py <argv>``."""
    return " ".join(["python", f"benchmarks/{name}.py", *map(shlex.quote, argv)])


def publish(name: str, title: str, body: Sequence[str], args: argparse.Namespace, argv: Sequence[str]) -> Path:
    """Write the table ``body`` (Markdown lines) under ``title`` with the command, machine and commit to
    ``<args.out>/<name>.md``; with ``args.update_docs``, also replace the section of ``args.docs`` between the
    benchmark's markers. Returns the table's path."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    section = [
        f"`{command(name, argv)}`",
        "",
        f"Machine: {machine()}. Commit: `{commit()}`. Load average at the end: {load:.1f}"
        + (" (smoke size: the numbers mean nothing)." if args.smoke else "."),
        "",
        *body,
    ]
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"{name}.md"
    path.write_text("\n".join([f"# {title}", "", *section]).rstrip("\n") + "\n")
    print(f"wrote {path}")
    if args.update_docs:
        update_docs(args.docs, name, section)
        print(f"updated {args.docs} (section {name})")
    return path


def update_docs(docs: Path, name: str, section: Sequence[str]) -> None:
    """Replace the lines between ``<!-- bench:<name> -->`` and ``<!-- /bench:<name> -->`` of ``docs``."""
    start, end = f"<!-- bench:{name} -->", f"<!-- /bench:{name} -->"
    text = docs.read_text() if docs.exists() else ""
    if start not in text or end not in text or text.index(start) > text.index(end):
        raise SystemExit(f"{docs} has no section {start} ... {end}; add the two markers where the table goes")
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    docs.write_text(head + start + "\n" + "\n".join(section).strip("\n") + "\n" + end + tail)


def best_seconds(fn: Callable[[], object], repeats: int) -> float:
    """The shortest wall time of ``repeats`` calls of ``fn`` (results waited for), after one call that compiles."""
    import jax

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
    import jax

    for fn in fns.values():
        jax.block_until_ready(fn(*args))
    best = dict.fromkeys(fns, float("inf"))
    for _ in range(repeats):
        for name, fn in fns.items():
            start = time.perf_counter()
            jax.block_until_ready(fn(*args))
            best[name] = min(best[name], time.perf_counter() - start)
    return best


def random_play(agent, mdp, spec, hp, n_steps: int, key):
    """The (jitted) tabular agent's state after ``n_steps`` uniformly random actions on ``mdp`` (``update`` only, from
    ``agent.init(key, spec, hp)``): counts as early or late in a run as asked, without the agent's own policy."""
    import jax
    import numpy as np

    import jaxmdp
    from jaxmdp.experiment.agent_interface import Transition

    A = int(np.sum(np.asarray(mdp.action_mask)))

    @jax.jit
    def run(key):
        def body(c, k):
            obs, env_state, st = c
            k_a, k_s = jax.random.split(k)
            a = jax.random.randint(k_a, (), 0, A)
            obs2, env_state2, r, term, _, info = jaxmdp.step(k_s, env_state, a, mdp)
            tr = Transition(obs=obs, action=a, reward=r, next_obs=info["final_observation"], h=env_state.h,
                            terminated=term)
            return (obs2, env_state2, agent.update(st, tr)), None

        obs, env_state = jaxmdp.reset(jax.random.fold_in(key, 1), mdp)
        carry = (obs, env_state, agent.init(key, spec, hp))
        (_, _, state), _ = jax.lax.scan(body, carry, jax.random.split(key, n_steps))
        return state

    return run(key)
