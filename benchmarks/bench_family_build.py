"""Host-side construction time of the MiniGrid and Taxi families (``jaxmdp.make``, arrays included), beside the
reference package's build times where it gives one (Colosseum 1.2 on the same kind of machine, docs/benchmark.md §10).

Each configuration is built ``--repeats`` times in this process; the table gives the minimum and the median.

    python benchmarks/bench_family_build.py [--repeats 3] [--update-docs]
    python benchmarks/bench_family_build.py --smoke
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Sequence

import _common

NAME = "bench_family_build"

# (family, setting, parameters, reference build seconds or None)
CONFIGS = [
    ("MiniGridEmpty", "continuous", dict(size=4), 0.13),
    ("MiniGridEmpty", "continuous", dict(size=8), 0.51),
    ("MiniGridEmpty", "continuous", dict(size=11), 1.6),
    ("MiniGridEmpty", "continuous", dict(size=14), 2.5),
    ("MiniGridEmpty", "episodic", dict(size=8), 0.5),
    ("MiniGridRooms", "continuous", dict(room_size=3, n_rooms=9), None),
    ("MiniGridRooms", "episodic", dict(room_size=5, n_rooms=9), None),
    ("Taxi", "continuous", dict(size=5), None),
    ("Taxi", "episodic", dict(size=7), None),
    ("MiniGridDoorKey", "continuous", dict(size=8), None),
    ("MiniGridDoorKey", "episodic", dict(size=8), None),
]
SMOKE_CONFIGS = [CONFIGS[0], ("Taxi", "continuous", dict(size=4, length=1, width=1, space=1, n_locations=3), None)]


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    _common.add_common_args(parser)
    args = parser.parse_args(argv)

    from jaxmdp.experiment import compilation

    folder, stats = compilation.setup_compilation(args.no_compile_cache)
    start = time.perf_counter()
    import jaxmdp

    jaxmdp.make("RiverSwim", episodic=False, seed=0, size=3)  # warm up JAX's array creation
    rows = []
    for family, setting, params, reference in SMOKE_CONFIGS if args.smoke else CONFIGS:
        times = []
        for _ in range(1 if args.smoke else args.repeats):
            t0 = time.perf_counter()
            m = jaxmdp.make(family, episodic=setting == "episodic", seed=0, p_rand=0.1, **params)
            times.append(time.perf_counter() - t0)
        rows.append(dict(family=family, setting=setting, params=" ".join(f"{k}={v}" for k, v in params.items()),
                         S=m.n_states, A=m.n_actions, H=m.H, min_s=min(times), median_s=statistics.median(times),
                         reference=reference))
        print(rows[-1], flush=True)
    body = [
        f"Best and median of {1 if args.smoke else args.repeats} builds in one process (`jaxmdp.make`, arrays "
        "included, `p_rand = 0.1`, seed 0); reference: Colosseum 1.2's build time where docs/benchmark.md §10 gives one.",
        "",
        "| family | setting | parameters | S | A | H | best s | median s | reference s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    body += [f"| {r['family']} | {r['setting']} | {r['params']} | {r['S']} | {r['A']} | {r['H'] or ''} | "
             f"{r['min_s']:.4f} | {r['median_s']:.4f} | {'' if r['reference'] is None else r['reference']} |"
             for r in rows]
    _common.publish(NAME, "Family construction against the reference", body, args, argv)
    print(compilation.time_report(time.perf_counter() - start, stats.snapshot(), folder), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
