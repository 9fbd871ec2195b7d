"""Benchmark: compile once. The main job and the 80-MDP hardness call, each run twice in fresh processes that share a
new, empty persistent compilation cache: the first run fills it (cold), the second reads it (warm).

Each run is its own Python process (the persistent cache is what carries over; JAX's in-memory caches do not), with
``JAXMDP_COMPILATION_CACHE`` pointing at a temporary folder so the user's own cache neither helps nor changes. Reported
per run: the seconds spent tracing, lowering and compiling (or loading from the cache) as counted by
:mod:`jaxmdp.experiment.compilation`, the total, and the cache's hits and misses.

* main job: ``jaxmdp-sweep-prand`` with its defaults (the README's command), writing into a temporary folder;
* hardness call: :func:`hardness.measures_many` on the 80 benchmark MDPs (docs/benchmark.md §3, seed 0), timed from
  the call to its result, compilation included (building the MDPs is timed apart);
* the runner's programs (``--only programs``): for each tabular agent, in a fresh process without a persistent cache,
  ``runner.run`` on two seeds of RiverSwim (5 states) and XLA's compile seconds of each of its three programs (the
  indicator constants, the initialisation, the chunk), from JAX's compile log.

    python benchmarks/bench_compile.py                 # both, cold then warm
    python benchmarks/bench_compile.py --only hardness
    python benchmarks/bench_compile.py --only programs
    python benchmarks/bench_compile.py --smoke         # the hardness call on two small MDPs
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import _common

NAME = "bench_compile"
ROOT = _common.ROOT
_RESULT = "BENCH_COMPILE_RESULT "
#: The agents of the programs measurement (every tabular agent of the benchmark).
PROGRAM_AGENTS = ("q_learning_episodic", "q_learning_continuous", "psrl_episodic", "psrl_continuous", "ucrl2")


def _hardness_call(smoke: bool) -> None:
    """The child process of the hardness measurement: prints one JSON line of its timings."""
    import jax

    from jaxmdp.experiment import compilation

    _, stats = compilation.setup_compilation()
    import hardness
    from hardness.benchmark import suite as benchmark_suite

    t0 = time.perf_counter()
    if smoke:
        import jaxmdp

        mdps = [jaxmdp.make("RiverSwim", episodic=False, seed=0, size=3),
                jaxmdp.make("DeepSea", episodic=False, seed=0, size=3)]
    else:
        mdps = [m for _, m in benchmark_suite.build_suite(seed=0)]
    t1 = time.perf_counter()
    before = stats.snapshot()
    jax.block_until_ready(hardness.measures_many(mdps, variant="paper"))
    t2 = time.perf_counter()
    after = stats.snapshot()
    print(_RESULT + json.dumps({
        "build_s": t1 - t0,
        "total_s": t2 - t1,
        "compile_s": after["compile_s"] - before["compile_s"],
        "cache_hits": after["cache_hits"] - before["cache_hits"],
        "cache_misses": after["cache_misses"] - before["cache_misses"],
    }), flush=True)


def _programs_call(name: str) -> None:
    """The child process of the programs measurement: prints one JSON line, XLA's compile seconds per program."""
    import logging
    import re

    import jax

    import agents
    import jaxmdp
    from jaxmdp.experiment import runner

    seconds: dict[str, float] = {}
    pattern = re.compile(r"Finished XLA compilation of jit\((\w+)\) in ([0-9.e-]+) sec")

    class Log(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            if m := pattern.search(record.getMessage()):
                seconds[m.group(1)] = seconds.get(m.group(1), 0.0) + float(m.group(2))

    logging.getLogger("jax").addHandler(Log(logging.DEBUG))
    agent = agents.get(name)
    mdp = jaxmdp.make("RiverSwim", episodic=agent.episodic, seed=0, size=5)
    grid = runner.product([mdp], [agent.default_hparams], seeds=[0, 1])
    with jax.log_compiles(True):
        res = runner.run(agent, grid, 200, log_period=20, n_records=4)
    print(_RESULT + json.dumps({"agent": name, "compile_s": res.compile_s,
                                **{k: seconds.get(k, 0.0) for k in ("constants", "init_carry", "chunk")}}),
          flush=True)


def _programs(name: str) -> dict:
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child-programs", name],
                          env={**os.environ, "JAXMDP_COMPILATION_CACHE": "off"}, capture_output=True, text=True,
                          check=True)
    line = [x for x in proc.stdout.splitlines() if x.startswith(_RESULT)][-1]
    return json.loads(line[len(_RESULT):])


def _main_job(cache: Path, out: Path) -> dict:
    """Runs the README's main job in a fresh process; its compile time from the ``time:`` line it prints."""
    env = {**os.environ, "JAXMDP_COMPILATION_CACHE": str(cache)}
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "hardness.cli.sweep", "--out", str(out)], cwd=ROOT,
                          env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    line = [x for x in (proc.stdout + proc.stderr).splitlines() if x.startswith("time:")][-1]
    # "time: T s, of which compiling C s (...) and running R s (cache ...: H hits, M misses)"
    words = line.replace(",", " ").replace("(", " ").replace(")", " ").split()
    return {
        "total_s": float(words[1]),
        "compile_s": float(words[words.index("compiling") + 1]),
        "cache_hits": int(words[words.index("hits") - 1]),
        "cache_misses": int(words[words.index("misses") - 1]),
        "process_s": wall,
    }


def _hardness(cache: Path, smoke: bool) -> dict:
    env = {**os.environ, "JAXMDP_COMPILATION_CACHE": str(cache)}
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child-hardness"]
                          + (["--smoke"] if smoke else []), env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    line = [x for x in proc.stdout.splitlines() if x.startswith(_RESULT)][-1]
    return {**json.loads(line[len(_RESULT):]), "process_s": wall}


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--only", choices=["main", "hardness", "programs"], help="measure one of the three")
    p.add_argument("--child-hardness", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--child-programs", help=argparse.SUPPRESS)
    _common.add_common_args(p)
    args = p.parse_args(argv)
    if args.child_hardness:
        _hardness_call(args.smoke)
        return 0
    if args.child_programs:
        _programs_call(args.child_programs)
        return 0
    if args.smoke:
        args.only = "hardness"

    rows = []
    label_of = {"main": "main job (jaxmdp-sweep-prand)",
                "hardness": "2-MDP hardness.measures_many" if args.smoke else "80-MDP hardness.measures_many"}
    with tempfile.TemporaryDirectory(prefix="jaxmdp-bench-compile-") as tmp:
        tmp = Path(tmp)
        for what in ("main", "hardness"):
            if args.only not in (None, what):
                continue
            cache = tmp / f"cache-{what}"
            for run in ("cold", "warm"):
                r = _main_job(cache, tmp / "out") if what == "main" else _hardness(cache, args.smoke)
                rows.append({"what": label_of[what], "run": run, **r})
                print(f"{label_of[what]:36s} {run}: total {r['total_s']:.1f} s, compiling {r['compile_s']:.1f} s "
                      f"(cache {r['cache_hits']} hits, {r['cache_misses']} misses), process {r['process_s']:.1f} s",
                      flush=True)
        programs = []
        if args.only in (None, "programs") and not args.smoke:
            for name in PROGRAM_AGENTS:
                programs.append(_programs(name))
                print("{agent:24s} constants {constants:.2f} s, initialisation {init_carry:.2f} s, chunk {chunk:.2f} s"
                      .format(**programs[-1]), flush=True)

    body = [
        "Each run is a fresh process; the two runs of a row pair share a new, empty persistent compilation cache "
        "(cold: fills it, warm: reads it). `total` is the command's own total (main job) or the call from start to "
        "result, compilation included (hardness); `process` adds interpreter start-up and imports.",
        "",
        "| what | run | total s | compiling s | cache hits | cache misses | process s |",
        "|---|---|---|---|---|---|---|",
    ]
    body += [f"| {r['what']} | {r['run']} | {r['total_s']:.1f} | {r['compile_s']:.1f} | {r['cache_hits']} | "
             f"{r['cache_misses']} | {r['process_s']:.1f} |" for r in rows]
    if programs:
        body += ["", "The runner's programs, cold (a fresh process, no persistent cache; two seeds of RiverSwim, 5 "
                 "states): XLA's compile seconds of each program, and the runner's `compile_s` (tracing and lowering "
                 "included).", "",
                 "| agent | constants s | initialisation s | chunk s | runner compile_s |", "|---|---|---|---|---|"]
        body += [f"| {r['agent']} | {r['constants']:.2f} | {r['init_carry']:.2f} | {r['chunk']:.2f} | "
                 f"{r['compile_s']:.2f} |" for r in programs]
    _common.publish(NAME, "Compilation: cold and warm runs", body, args, argv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
