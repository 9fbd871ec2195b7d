"""Benchmark the hardness measures: time against the number of states, and the whole benchmark suite in one call.

Writes ``results/bench_hardness.md`` and ``results/bench_hardness.csv``. Compile time (``jit(...).lower().compile()``)
and run time (best of ``--repeats`` executions of the compiled program) are reported separately.

1. Scaling, continuous, up to ~2000 states, for MiniGridEmpty, SimpleGrid and Taxi when registered. When a family is
   not registered a stand-in is timed instead and labelled as such: ``grid(custom)``, an ``n x n`` grid built with
   ``custom_mdp`` (4 moves, ``p_lazy = 0.1``, reward in a corner), which has the structure of SimpleGrid.
   Each size also times one Jacobi sweep of the all-targets hitting-time backup in the dense form
   (``einsum`` over ``T[S, A, S]``) and in the successor-list form the diameter uses.
2. All benchmark MDPs (``hardness.benchmark_suite``, seed 0) of the registered families: continuous and episodic
   stacks, ``jit(vmap(measures))`` for both variants.

Usage: ``PYTHONPATH=$PWD python scripts/bench_hardness.py [--max-states 2100] [--repeats 2] [--quick]``.
"""

from __future__ import annotations

import argparse
import csv
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import hardness
import jaxmdp
from hardness import benchmark_suite
from hardness.diameter import _expect_columns
from jaxmdp import episodic

RESULTS = Path(__file__).resolve().parents[1] / "results"

# Reference timings (shared/reference/colosseum-timings.md, warm numba, one core): (family, S) -> diameter seconds.
REFERENCE_DIAMETER_S = {
    ("MiniGridEmpty", 64): 0.01, ("MiniGridEmpty", 256): 0.43, ("MiniGridEmpty", 484): 10.0,
    ("MiniGridEmpty", 784): 39.1, ("MiniGridEmpty", 1024): 74.0,
    ("SimpleGrid", 49): 0.01, ("SimpleGrid", 225): 0.53, ("SimpleGrid", 400): 9.9, ("SimpleGrid", 625): 30.2,
    ("SimpleGrid", 1024): 117.0,
}


def grid_mdp(n: int, p_lazy: float = 0.1) -> jaxmdp.MDP:
    """The labelled stand-in: an ``n x n`` grid, moves up/down/left/right (walls keep the agent in place), a lazy
    step with probability ``p_lazy``, reward 1 for any action in the far corner."""
    S = n * n
    T = np.zeros((S, 4, S))
    R = np.zeros((S, 4))
    for x in range(n):
        for y in range(n):
            s = x * n + y
            for a, (dx, dy) in enumerate(((0, 1), (0, -1), (1, 0), (-1, 0))):
                t = min(max(x + dx, 0), n - 1) * n + min(max(y + dy, 0), n - 1)
                T[s, a, t] += 1.0 - p_lazy
                T[s, a, s] += p_lazy
            if x == n - 1 and y == n - 1:
                R[s] = 1.0
    return jaxmdp.custom_mdp(T, R, info=jaxmdp.MDPInfo(family="grid(custom)"))


def episodic_grid_mdp(n: int, p_lazy: float = 0.1, H: int | None = None) -> jaxmdp.MDP:
    """Episodic stand-in: :func:`grid_mdp` with three starting corners and ``H = 2 n + 3`` by default."""
    m = grid_mdp(n, p_lazy)
    P0 = np.zeros(n * n)
    P0[[0, n - 1, n * (n - 1)]] = 1.0 / 3.0
    H = 2 * n + 3 if H is None else H
    return jaxmdp.custom_mdp(m.T, m.R, P0, H=H, info=jaxmdp.MDPInfo(family="grid(custom)"))


EPISODIC_GRID_SIZES = [8, 12, 16, 20]

FAMILY_SIZES = {
    # family -> (size parameter values, extra kwargs); ~2000 states at the top.
    "MiniGridEmpty": ([4, 8, 11, 14, 16, 19, 22], dict(p_lazy=0.1)),
    "SimpleGrid": ([7, 15, 20, 25, 32, 40, 45], dict(p_lazy=0.1)),
    "Taxi": ([4, 5, 6, 7], dict(length=1, width=1, space=1, n_locations=3, p_lazy=0.1)),
}
GRID_SIZES = [8, 15, 20, 25, 32, 40, 45]


def scaling_mdps(max_states: int, quick: bool) -> list[tuple[str, jaxmdp.MDP]]:
    out = []
    stand_in = False
    for fam, (sizes, extra) in FAMILY_SIZES.items():
        if fam not in jaxmdp.families():
            stand_in = True
            continue
        for size in sizes[:3] if quick else sizes:
            try:
                m = jaxmdp.make(fam, episodic=False, seed=0, size=size, randomize_actions=False, **extra)
            except ValueError as err:  # a family may name its parameters differently
                print(f"skip {fam} size {size}: {err}")
                continue
            if m.n_states <= max_states:
                out.append((fam, m))
    if stand_in:
        for n in GRID_SIZES[:3] if quick else GRID_SIZES:
            if n * n <= max_states:
                out.append(("grid(custom)", grid_mdp(n)))
    return out


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


MEASURES = {
    "diameter": lambda m, v: hardness.diameter(m, variant=v),
    "value_norm": lambda m, v: hardness.value_norm(m, variant=v),
    "gaps": lambda m, v: hardness.sum_reciprocal_gaps(m, variant=v),
}


def sweep_timings(m: jaxmdp.MDP, repeats: int) -> tuple[float, float]:
    """One all-targets Jacobi backup ``V[S, S] -> 1 + min_a P V``: dense einsum vs successor lists (seconds)."""
    V = jnp.ones((m.n_states, m.n_states), m.dtype)

    def dense(m, V):
        return jnp.min(1.0 + jnp.einsum("sat,te->sae", m.T, V), axis=1)

    def succ(m, V):
        return jnp.min(1.0 + _expect_columns(m.succ, m.succ_p, V), axis=1)

    return timed(dense, m, V, repeats=repeats)[1], timed(succ, m, V, repeats=repeats)[1]


def run_scaling(args, rows):
    todo = scaling_mdps(args.max_states, args.quick)
    todo += [("grid(custom)", episodic_grid_mdp(n)) for n in (EPISODIC_GRID_SIZES[:2] if args.quick else EPISODIC_GRID_SIZES)]
    for fam, m in todo:
        forms = episodic.continuous_form(m) if m.episodic else None
        m = m.strip()
        t_dense, t_succ = sweep_timings(m, args.repeats)
        for variant in ("paper", "colosseum"):
            for name, fn in MEASURES.items():
                if name == "value_norm":
                    call = lambda x, cf, v=variant: hardness.value_norm(x, variant=v, continuous_form=cf)  # noqa: E731
                else:
                    call = lambda x, cf, fn=fn, v=variant: fn(x, v)  # noqa: E731
                tc, tr, out = timed(call, m, forms, repeats=args.repeats)
                setting = f"episodic H={m.H}" if m.episodic else "continuous"
                row = dict(
                    part="scaling", family=fam, S=m.n_states, setting=setting, variant=variant, measure=name,
                    n_mdps=1, compile_s=round(tc, 3), run_s=round(tr, 4), value=float(out.value),
                    converged=bool(out.converged), sweep_dense_ms=round(1e3 * t_dense, 3),
                    sweep_succ_ms=round(1e3 * t_succ, 3),
                )
                rows.append(row)
                print(row, flush=True)


def run_suite(args, rows):
    suite = benchmark_suite.build_suite(seed=0, skip_missing=True)
    for is_episodic in (False, True):
        members = [(e, m) for e, m in suite if e.episodic == is_episodic]
        if not members:
            continue
        batch = jaxmdp.stack([m for _, m in members])
        setting = "episodic" if is_episodic else "continuous"
        forms = episodic.stack_continuous_forms([episodic.continuous_form(m) for _, m in members]) if is_episodic else None
        for variant in ("paper", "colosseum"):
            def all_measures(b, cf, v=variant):
                return jax.vmap(lambda m, c: hardness.measures(m, variant=v, continuous_form=c))(b, cf)

            tc, tr, out = timed(all_measures, batch, forms, repeats=args.repeats)
            row = dict(
                part="suite", family="+".join(sorted({e.family for e, _ in members})), S=batch.n_states,
                setting=setting, variant=variant, measure="all three", n_mdps=len(members), compile_s=round(tc, 3),
                run_s=round(tr, 4), value=float("nan"),
                converged=bool(np.all(out.diameter.converged) & np.all(out.value_norm.converged)),
                sweep_dense_ms=None, sweep_succ_ms=None,
            )
            rows.append(row)
            print(row, flush=True)
    return len(suite)


def run_stand_in_suite(args, rows):
    """The 80-MDP workload with stand-ins for the families not registered: one labelled grid per entry with the
    entry's seed-0 number of states (``ceil(sqrt(S))^2``) and horizon, three starts for the episodic ones."""
    missing = [e for e in benchmark_suite.BENCHMARK if e.family not in jaxmdp.families()]
    if not missing:
        return
    for is_episodic in (False, True):
        entries = [e for e in benchmark_suite.BENCHMARK if e.episodic == is_episodic]
        n = [int(np.ceil(np.sqrt(e.n_states))) for e in entries]
        members = [episodic_grid_mdp(k, H=e.H) if is_episodic else grid_mdp(k) for k, e in zip(n, entries)]
        batch = jaxmdp.stack(members)
        forms = episodic.stack_continuous_forms([episodic.continuous_form(m) for m in members]) if is_episodic else None
        for variant in ("paper", "colosseum"):
            def all_measures(b, cf, v=variant):
                return jax.vmap(lambda m, c: hardness.measures(m, variant=v, continuous_form=c))(b, cf)

            tc, tr, out = timed(all_measures, batch, forms, repeats=1)
            row = dict(
                part="suite(stand-in)", family="grid(custom)", S=batch.n_states,
                setting="episodic" if is_episodic else "continuous", variant=variant, measure="all three",
                n_mdps=len(members), compile_s=round(tc, 3), run_s=round(tr, 4), value=float("nan"),
                converged=bool(np.all(out.diameter.converged) & np.all(out.value_norm.converged)),
                sweep_dense_ms=None, sweep_succ_ms=None,
            )
            rows.append(row)
            print(row, flush=True)


def write(rows, n_suite, args):
    RESULTS.mkdir(exist_ok=True)
    keys = list(rows[0])
    with open(RESULTS / "bench_hardness.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    lines = [
        "# Hardness measures: timings",
        "",
        f"Machine: {platform.machine()}, {jax.device_count()} x {jax.devices()[0].platform}, jax {jax.__version__}; "
        f"best of {args.repeats} runs; compile time listed separately. Written by `scripts/bench_hardness.py`.",
        "",
        "## Time against the number of states (one MDP per call)",
        "",
        "`grid(custom)` is the labelled stand-in used while a family is not registered (see the script docstring). "
        "`sweep` columns: one all-targets Jacobi backup, dense `einsum` over `T[S,A,S]` vs successor lists.",
        "",
        "| family | setting | S | variant | diameter run s | value norm run s | gaps run s | compile s (d/vn/g) | diameter "
        "| sweep dense ms | sweep succ ms | reference diameter s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    scaling = [r for r in rows if r["part"] == "scaling"]
    keyset = sorted({(r["setting"], r["family"], r["S"], r["variant"]) for r in scaling})
    for setting, fam, S, variant in keyset:
        by = {r["measure"]: r for r in scaling if (r["setting"], r["family"], r["S"], r["variant"]) == (setting, fam, S, variant)}
        d, vn, g = by["diameter"], by["value_norm"], by["gaps"]
        ref = REFERENCE_DIAMETER_S.get((fam, S), "")
        lines.append(
            f"| {fam} | {setting} | {S} | {variant} | {d['run_s']} | {vn['run_s']} | {g['run_s']} | "
            f"{d['compile_s']}/{vn['compile_s']}/{g['compile_s']} | {d['value']:.4f}{'' if d['converged'] else ' (!)'} "
            f"| {d['sweep_dense_ms']} | {d['sweep_succ_ms']} | {ref} |"
        )
    lines += [
        "",
        f"## Benchmark suite in one batched call ({n_suite} of 80 MDPs: those of the registered families)",
        "",
        "| setting | variant | MDPs | padded S | compile s | run s | all converged |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["part"] == "suite":
            lines.append(
                f"| {r['setting']} | {r['variant']} | {r['n_mdps']} | {r['S']} | {r['compile_s']} | {r['run_s']} | "
                f"{r['converged']} |"
            )
    stand_in = [r for r in rows if r["part"] == "suite(stand-in)"]
    if stand_in:
        lines += [
            "",
            "## The 80-MDP workload with stand-ins (while families are missing)",
            "",
            "Each benchmark entry replaced by a `grid(custom)` of its seed-0 size (`ceil(sqrt(S))^2` states, 4 "
            "actions, `p_lazy = 0.1`) and horizon; one batched call per setting kind, all three measures.",
            "",
            "| setting | variant | MDPs | padded S | compile s | run s | all converged |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in stand_in:
            lines.append(
                f"| {r['setting']} | {r['variant']} | {r['n_mdps']} | {r['S']} | {r['compile_s']} | {r['run_s']} | "
                f"{r['converged']} |"
            )
        for v in ("paper", "colosseum"):
            tot = sum(r["run_s"] for r in stand_in if r["variant"] == v)
            comp = sum(r["compile_s"] for r in stand_in if r["variant"] == v)
            lines.append(f"\nTotal {v}: run {tot:.1f} s + compile {comp:.1f} s.")
    lines += [
        "",
        "Reference (shared/reference/colosseum-timings.md, warm, one core): diameter MiniGridEmpty continuous "
        "64/256/484/784/1024 states 0.01/0.43/10.0/39.1/74 s; SimpleGrid 49/225/400/625/1024 states "
        "0.01/0.53/9.9/30.2/117 s; value norm and gaps <= 2 s; episodic diameter MiniGridEmpty 64/144/196/256 "
        "states 0.27/4.3/11.8/28.4 s.",
        "",
    ]
    (RESULTS / "bench_hardness.md").write_text("\n".join(lines))
    print("\n".join(lines))


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--max-states", type=int, default=2100)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--quick", action="store_true", help="three smallest sizes only")
    args = p.parse_args()
    rows: list[dict] = []
    n_suite = run_suite(args, rows)
    if not args.quick:
        run_stand_in_suite(args, rows)
    run_scaling(args, rows)
    write(rows, n_suite, args)


if __name__ == "__main__":
    main()
