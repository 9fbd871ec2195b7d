"""Host-side construction time of the MiniGrid and Taxi families (``jaxmdp.make``, arrays included).

Each configuration is built ``--repeats`` times in this process; the minimum and the median are written to
``results/bench_family_build/build_times.csv``. The reference package's build times (Colosseum 1.2, same kind of
machine, docs/benchmark.md §10) are listed next to ours where it gives one.

    PYTHONPATH=$PWD python scripts/bench_family_build.py
"""

from __future__ import annotations

import argparse
import csv
import statistics
import time
from pathlib import Path

import jaxmdp
from jaxmdp.experiment import compilation

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("results/bench_family_build"))
    compilation.add_cache_flag(parser)
    args = parser.parse_args()
    cache_folder, compile_stats = compilation.setup_compilation(args.no_compile_cache)
    t_script = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    jaxmdp.make("RiverSwim", episodic=False, seed=0, size=3)  # warm up JAX's array creation
    rows = []
    for family, setting, params, reference in CONFIGS:
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            m = jaxmdp.make(family, episodic=setting == "episodic", seed=0, p_rand=0.1, **params)
            times.append(time.perf_counter() - t0)
        row = dict(
            family=family,
            setting=setting,
            params=" ".join(f"{k}={v}" for k, v in params.items()),
            S=m.n_states,
            A=m.n_actions,
            H=m.H,
            min_s=round(min(times), 4),
            median_s=round(statistics.median(times), 4),
            reference_build_s=reference,
        )
        rows.append(row)
        print(row)
    path = args.out / "build_times.csv"
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {path}")
    print(compilation.time_report(time.perf_counter() - t_script, compile_stats.snapshot(), cache_folder))


if __name__ == "__main__":
    main()
