"""Benchmark the hardness measures: time against the number of states, and the 80 benchmark MDPs in one call.

Writes ``results/benchmarks/bench_hardness.csv`` (one row per timing, appended as it is measured, so an interrupted
run keeps what it finished) and the tables (``results/benchmarks/bench_hardness.md``; ``--update-docs``: also
docs/performance.md).

1. Scaling: each measure of one MDP per call, MiniGridEmpty, SimpleGrid and Taxi up to ~2000 states (continuous) and
   MiniGridEmpty / SimpleGrid episodic; compile time (``jit(...).lower().compile()``) and run time (best of
   ``--repeats`` executions of the compiled program) separately. Each size also times one all-targets backup of
   the hitting times in the dense form (``einsum`` over ``T[S, A, S]``) and in the successor-list form the diameter
   uses.
2. Suite: all 80 MDPs of docs/benchmark.md §3 (seed 0) in one :func:`hardness.measures_many` call, both
   variants: the first call (compilation of the size buckets' programs + run) and the best warm call (run only;
   compile = first - warm). ``--single-stack-baseline`` also times the 40 continuous members in one padded stack
   mapped with ``lax.map``, the layout ``measures_many`` replaces.

    python benchmarks/bench_hardness.py [--max-states 2100] [--repeats 2] [--quick] [--update-docs]
    python benchmarks/bench_hardness.py --smoke
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import hardness
import jaxmdp
from jaxmdp.experiment import compilation
from hardness.batched import map_measures
from hardness.benchmark import suite as benchmark_suite
from hardness.diameter import _expect_columns
from jaxmdp import episodic

import _common

NAME = "bench_hardness"

# Reference timings (docs/benchmark.md §10, warm numba, one core): (family, S) -> diameter seconds.
REFERENCE_DIAMETER_S = {
    ("MiniGridEmpty", 64): 0.01, ("MiniGridEmpty", 256): 0.43, ("MiniGridEmpty", 484): 10.0,
    ("MiniGridEmpty", 784): 39.1, ("MiniGridEmpty", 1024): 74.0,
    ("SimpleGrid", 49): 0.01, ("SimpleGrid", 225): 0.53, ("SimpleGrid", 400): 9.9, ("SimpleGrid", 625): 30.2,
    ("SimpleGrid", 1024): 117.0,
}

# family -> (size values, extra kwargs); ~2000 states at the top of the continuous ones.
CONTINUOUS_SIZES = {
    "MiniGridEmpty": ([4, 8, 11, 14, 16, 19, 22, 24], dict(p_lazy=0.1)),
    "SimpleGrid": ([7, 15, 20, 25, 32, 40, 45], dict(p_lazy=0.1)),
    "Taxi": ([4, 5, 6, 7], dict(length=1, width=1, space=1, n_locations=3, p_lazy=0.1)),
}
EPISODIC_SIZES = {
    "MiniGridEmpty": ([6, 10, 14, 18], dict(p_lazy=0.1)),
    "SimpleGrid": ([10, 15, 20], dict(p_lazy=0.1)),
}
MEASURES = ("diameter", "value_norm", "sum_reciprocal_gaps")
FIELDS = ("part", "family", "setting", "S", "H", "variant", "measure", "n_mdps", "compile_s", "run_s", "value",
          "converged", "sweep_dense_ms", "sweep_succ_ms")


class Rows:
    """The measured rows, each appended to the CSV (and printed) as soon as it exists."""

    def __init__(self, path: Path):
        self.path, self.rows = path, []
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w", newline="") as f:
            csv.DictWriter(f, fieldnames=FIELDS).writeheader()

    def add(self, **row):
        row = {k: row.get(k, "") for k in FIELDS}
        self.rows.append(row)
        with open(self.path, "a", newline="") as f:
            csv.DictWriter(f, fieldnames=FIELDS).writerow(row)
        print(row, flush=True)


def timed(fn, *args, repeats: int):
    """(compile seconds, best run seconds, output) of ``jax.jit(fn)(*args)``."""
    t0 = time.perf_counter()
    compiled = jax.jit(fn).lower(*args).compile()
    t_compile = time.perf_counter() - t0
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = jax.block_until_ready(compiled(*args))
        best = min(best, time.perf_counter() - t0)
    return t_compile, best, out


def one_measure(name: str, variant: str):
    def call(m, cf):
        if name == "value_norm":
            return hardness.value_norm(m, variant=variant, continuous_form=cf)
        return getattr(hardness, name)(m, variant=variant)

    return call


def sweep_timings(m: jaxmdp.MDP, repeats: int) -> tuple[float, float]:
    """One all-targets backup ``V[S, S] -> 1 + min_a P V``: dense einsum vs successor lists (seconds)."""
    V = jnp.ones((m.n_states, m.n_states), m.dtype)

    def dense(m, V):
        return jnp.min(1.0 + jnp.einsum("sat,te->sae", m.T, V), axis=1)

    def succ(m, V):
        return jnp.min(1.0 + _expect_columns(m.succ, m.succ_p, V), axis=1)

    return timed(dense, m, V, repeats=repeats)[1], timed(succ, m, V, repeats=repeats)[1]


def scaling_mdps(args) -> list[tuple[str, jaxmdp.MDP]]:
    if args.smoke:
        return [("MiniGridEmpty", jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=3, randomize_actions=False,
                                             p_lazy=0.1))]
    out = []
    for is_episodic, table in ((False, CONTINUOUS_SIZES), (True, EPISODIC_SIZES)):
        for fam, (sizes, extra) in table.items():
            for size in sizes[:2] if args.quick else sizes:
                m = jaxmdp.make(fam, episodic=is_episodic, seed=0, size=size, randomize_actions=False, **extra)
                if m.n_states <= args.max_states:
                    out.append((fam, m))
    return out


def run_scaling(args, rows: Rows):
    for fam, m in scaling_mdps(args):
        forms = episodic.continuous_form(m) if m.episodic else None
        m = m.strip()
        t_dense, t_succ = sweep_timings(m, args.repeats)
        for variant in ("paper",) if args.smoke else ("paper", "colosseum"):
            for name in MEASURES[:1] if args.smoke else MEASURES:
                tc, tr, out = timed(one_measure(name, variant), m, forms, repeats=args.repeats)
                rows.add(
                    part="scaling", family=fam, setting="episodic" if m.episodic else "continuous", S=m.n_states,
                    H=m.H or "", variant=variant, measure=name, n_mdps=1, compile_s=round(tc, 3), run_s=round(tr, 4),
                    value=float(out.value), converged=bool(out.converged), sweep_dense_ms=round(1e3 * t_dense, 3),
                    sweep_succ_ms=round(1e3 * t_succ, 3),
                )


def run_suite(args, rows: Rows):
    t0 = time.perf_counter()
    suite = benchmark_suite.build_suite(seed=0)
    print(f"built {len(suite)} benchmark MDPs in {time.perf_counter() - t0:.1f} s", flush=True)
    mdps = [m for _, m in suite]
    for variant in ("paper", "colosseum"):
        t0 = time.perf_counter()
        out = jax.block_until_ready(hardness.measures_many(mdps, variant=variant))
        first = time.perf_counter() - t0
        warm = np.inf
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            out = jax.block_until_ready(hardness.measures_many(mdps, variant=variant))
            warm = min(warm, time.perf_counter() - t0)
        converged = all(bool(np.all(getattr(out, k).converged)) for k in MEASURES)
        rows.add(
            part="suite", family="all 8", setting="both", S=max(m.n_states for m in mdps), variant=variant,
            measure="all three", n_mdps=len(mdps), compile_s=round(first - warm, 2), run_s=round(warm, 2),
            converged=converged,
        )
    if args.single_stack_baseline:
        cont = [m for m in mdps if not m.episodic]
        batch = jaxmdp.stack(cont).strip()
        tc, tr, out = timed(map_measures, batch, repeats=1)
        rows.add(
            part="suite(one padded stack)", family="all 8", setting="continuous", S=batch.n_states, variant="paper",
            measure="all three", n_mdps=len(cont), compile_s=round(tc, 2), run_s=round(tr, 2),
            converged=bool(np.all(out.diameter.converged)),
        )


def body(rows: list[dict], args) -> list[str]:
    """The tables' lines: the 80-MDP call, then time against the number of states."""
    lines = [
        f"Best of {args.repeats} runs; compile time listed separately.",
        "",
        "All 80 benchmark MDPs in one `hardness.measures_many` call:",
        "",
        "| variant | MDPs | largest S | compile s | run s | all converged |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["part"].startswith("suite"):
            label = r["variant"] + (" (40 continuous, one padded stack, lax.map)" if "stack" in r["part"] else "")
            lines.append(f"| {label} | {r['n_mdps']} | {r['S']} | {r['compile_s']} | {r['run_s']} | {r['converged']} |")
    lines += [
        "",
        "Time against the number of states (one MDP per call):",
        "",
        "`sweep` columns: one all-targets backup of the hitting times, dense `einsum` over `T[S,A,S]` vs successor "
        "lists. Reference: the reference package's diameter (docs/benchmark.md §10, warm, one core).",
        "",
        "| family | setting | S | variant | diameter run s | value norm run s | gaps run s | compile s (d/vn/g) "
        "| diameter | sweep dense ms | sweep succ ms | reference diameter s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    scaling = [r for r in rows if r["part"] == "scaling"]
    keys = []
    for r in scaling:
        k = (r["setting"], r["family"], r["S"], r["H"], r["variant"])
        if k not in keys:
            keys.append(k)
    for setting, fam, S, H, variant in keys:
        by = {r["measure"]: r for r in scaling if (r["setting"], r["family"], r["S"], r["H"], r["variant"]) == (
            setting, fam, S, H, variant)}
        if "diameter" not in by:
            continue
        blank = dict(run_s="-", compile_s="-")  # a measure not timed (--smoke times the diameter only)
        d, vn, g = (by.get(k, blank) for k in MEASURES)
        ref = REFERENCE_DIAMETER_S.get((fam, S), "") if setting == "continuous" else ""
        lines.append(
            f"| {fam} | {setting}{f' H={H}' if H else ''} | {S} | {variant} | {d['run_s']} | {vn['run_s']} | "
            f"{g['run_s']} | {d['compile_s']}/{vn['compile_s']}/{g['compile_s']} | "
            f"{d['value']:.4f}{'' if d['converged'] else ' (!)'} | {d['sweep_dense_ms']} | {d['sweep_succ_ms']} | {ref} |"
        )
    lines += [
        "",
        "Reference (docs/benchmark.md §10, warm, one core): diameter MiniGridEmpty continuous "
        "64/256/484/784/1024 states 0.01/0.43/10.0/39.1/74 s; SimpleGrid 49/225/400/625/1024 states "
        "0.01/0.53/9.9/30.2/117 s; value norm and gaps <= 2 s; episodic diameter MiniGridEmpty 64/144/196/256 "
        "states 0.27/4.3/11.8/28.4 s.",
    ]
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--max-states", type=int, default=2100)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--quick", action="store_true", help="two smallest sizes per family only")
    p.add_argument("--no-suite", action="store_true", help="skip the 80-MDP suite")
    p.add_argument("--single-stack-baseline", action="store_true", help="also time one padded stack (minutes)")
    _common.add_common_args(p)
    args = p.parse_args(argv)
    if args.smoke:
        args.repeats, args.no_suite = 1, True
    cache_folder, compile_stats = compilation.setup_compilation(args.no_compile_cache)
    t_script = time.perf_counter()
    rows = Rows(args.out / "bench_hardness.csv")
    if not args.no_suite:
        run_suite(args, rows)
    run_scaling(args, rows)
    _common.publish(NAME, "Hardness measures", body(rows.rows, args), args, argv)
    print(compilation.time_report(time.perf_counter() - t_script, compile_stats.snapshot(), cache_folder),
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
