"""Benchmark: eager calls of the dynamic-programming routines, jitted (:func:`jaxmdp.dynamic_programming.compiled`)
against the same functions unjitted, in one process.

Unjitted means every compiled routine of :mod:`jaxmdp.dynamic_programming` and :mod:`jaxmdp.values` replaced by the
function it wraps (``__wrapped__``) for the duration of the measurement, so that composite routines (e.g.
``solve_discounted``, which calls ``value_iteration`` and ``policy_iteration``) run as they did before the jit.

Each routine is called eagerly, as a researcher would in a notebook, on ``--mdps`` MDPs of one shape that differ in a
construction parameter (so in their labels). Unjitted, a routine with a loop compiles its loop again at every call;
jitted, the first call compiles and the others reuse the program. Reported per routine: seconds of the first call and
mean seconds of the others, for both.

    python scripts/bench_eager_calls.py              # RiverSwim, 12 states, 8 MDPs
    python scripts/bench_eager_calls.py --size 30 --mdps 4

Writes a section to ``docs/benchmarks/bench_eager_calls.md`` (with the command) unless ``--doc ''``.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path

import jax
import numpy as np

from bench_doc import append_section  # scripts/ is on the path of a script run as python scripts/NAME.py
import jaxmdp
from jaxmdp import dynamic_programming as dp
from jaxmdp import values

ROOT = Path(__file__).resolve().parent.parent


def _routines(continuous: jaxmdp.MDP, episodic: jaxmdp.MDP) -> dict:
    pi = dp.uniform_policy(continuous)
    return {
        "value_iteration": (dp.value_iteration, (continuous, 0.9)),
        "solve_discounted": (dp.solve_discounted, (continuous, 0.9)),
        "finite_horizon_value_iteration": (dp.finite_horizon_value_iteration, (episodic,)),
        "gain_vector": (dp.gain_vector, (continuous, pi)),
        "optimal_gain": (dp.optimal_gain, (continuous,)),
        "reference_values": (values.reference_values, (continuous,)),
    }


@contextlib.contextmanager
def _unjitted():
    """Every compiled routine of ``dp`` and ``values`` replaced by its unjitted function, restored on exit."""
    saved = [(m, name, f) for m in (dp, values) for name, f in vars(m).items() if hasattr(f, "jitted")]
    try:
        for m, name, f in saved:
            setattr(m, name, f.__wrapped__)
        yield
    finally:
        for m, name, f in saved:
            setattr(m, name, f)


def _seconds(fun, args) -> float:
    t = time.perf_counter()
    jax.block_until_ready(fun(*args))
    return time.perf_counter() - t


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=12, help="RiverSwim size (states)")
    p.add_argument("--mdps", type=int, default=8, help="MDPs of one shape, each called once per routine")
    p.add_argument("--doc", default=str(ROOT / "docs/benchmarks/bench_eager_calls.md"), help="'' to skip")
    args = p.parse_args(argv)
    if args.mdps < 2:
        p.error("--mdps must be at least 2 (the first call compiles)")
    p_lazy = np.linspace(0.05, 0.3, args.mdps)
    pairs = [
        tuple(jaxmdp.make("RiverSwim", episodic=e, seed=0, size=args.size, p_lazy=float(q)) for e in (False, True))
        for q in p_lazy
    ]
    rows = []
    for name in _routines(*pairs[0]):
        times = {}
        for kind in ("unjitted", "jitted"):
            calls = []
            with _unjitted() if kind == "unjitted" else contextlib.nullcontext():
                for pair in pairs:
                    fun, fargs = _routines(*pair)[name]
                    calls.append(_seconds(fun, fargs))
            times[kind] = (calls[0], float(np.mean(calls[1:])))
        u, j = times["unjitted"], times["jitted"]
        rows.append(f"| `{name}` | {u[0]:.2f} / {u[1]:.3f} | {j[0]:.2f} / {j[1]:.4f} | {u[1] / j[1]:.0f}x |")
        print(rows[-1], flush=True)
    if args.doc:
        append_section(args.doc, "Eager calls of the dynamic-programming routines: jitted against unjitted", argv, [
            f"RiverSwim, {args.size} states, {args.mdps} MDPs of one shape (`p_lazy` from 0.05 to 0.3); seconds of "
            "the first call / mean of the others.",
            "",
            "| routine | unjitted | jitted | later calls, unjitted / jitted |",
            "|---|---|---|---|",
            *rows,
        ])


if __name__ == "__main__":
    main()
