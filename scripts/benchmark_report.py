"""Write the benchmark report (tables as Markdown and LaTeX, cumulative-regret and hardness figures) of a
``scripts/run_benchmark.py`` output folder, from the batches finished so far (:mod:`hardness.benchmark.report`).

    python scripts/benchmark_report.py results/benchmark_quick
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hardness.benchmark import report


def main(argv: list[str] | None = None) -> list[Path]:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out", type=Path, help="the run's output folder")
    args = p.parse_args(argv)
    if not (args.out / "plan.json").exists() or not (args.out / "members.csv").exists():
        raise SystemExit(f"benchmark_report: {args.out} holds no benchmark run (plan.json and members.csv)")
    written = report.write_report(args.out)
    print("\n".join(map(str, written)))
    return written


if __name__ == "__main__":
    main()
    sys.exit(0)
