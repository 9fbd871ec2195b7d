"""``jaxmdp-completeness``: how well each hardness measure, and the paper's pair, orders the benchmark's MDPs as the
tuned agents' regret (paper §2.3's completeness; :mod:`hardness.analysis.completeness`).

Reads the ``members.csv`` of benchmark run folders (default: the committed full-budget runs in ``docs/tables/``),
computes the measures of the settings' MDPs for seeds ``0..N-1`` (``--measure-seeds``; kept in
``<out>/measures.csv`` and reused), and writes, per setting and learning agent, Spearman's rho and Kendall's tau-b
of every measure and of the diameter with the value norm (leave-one-MDP-out) with the per-step regret, with 95%
two-stage bootstrap intervals (MDPs, then seeds within MDPs): ``<out>/completeness.md``, ``completeness.csv`` and
``completeness_<setting>.png``.

    jaxmdp-completeness --out results/completeness
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from hardness.cli._common import add_cache_flag, compile_report

__all__ = ["DEFAULT_FOLDERS", "build_parser", "main"]

#: The committed full-budget benchmark runs of the tuned agents (the folders of Table 2 in docs/results.md, every
#: tabular agent at 20 seeds).
DEFAULT_FOLDERS = tuple(f"docs/tables/{name}" for name in (
    "benchmark_continuous_full_20seeds", "benchmark_episodic_full_20seeds_ql_random", "benchmark_tabular_20seeds"))


def build_parser() -> argparse.ArgumentParser:
    """The command's options (module docstring)."""
    parser = argparse.ArgumentParser(prog="jaxmdp-completeness", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folders", type=Path, nargs="*", default=[Path(p) for p in DEFAULT_FOLDERS],
                        help="benchmark run folders holding members.csv (default: the committed full-budget runs)")
    parser.add_argument("--out", type=Path, default=Path("results/completeness"), help="default %(default)s")
    parser.add_argument("--measure-seeds", type=int, default=1,
                        help="measure the MDPs of seeds 0..N-1; a regret seed without its own measure takes their "
                             "mean (default %(default)s)")
    parser.add_argument("--n-boot", type=int, default=1000, help="bootstrap resamples (default %(default)s)")
    parser.add_argument("--quiet", action="store_true", help="do not list the files written on stdout")
    add_cache_flag(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the completeness test (module docstring)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.measure_seeds < 1 or args.n_boot < 1:
        parser.error("--measure-seeds and --n-boot must be at least 1")
    for folder in args.folders:
        if not (folder / "members.csv").exists():
            parser.error(f"no members.csv in {folder}")
    with compile_report(args.no_compile_cache):
        written = run(args)
    if not args.quiet:
        print("\n".join(map(str, written)))
    return 0


def run(args: argparse.Namespace) -> list[Path]:
    """Measure what ``<out>/measures.csv`` lacks, then write the table, CSV and figures."""
    from hardness.analysis import completeness_benchmark as cb

    regrets = cb.read_regrets(args.folders)
    args.out.mkdir(parents=True, exist_ok=True)
    cache = args.out / "measures.csv"
    rows = cb.read_measures(cache) if cache.exists() else []
    seeds = list(range(args.measure_seeds))
    for set_name in sorted({k[0] for k in regrets}):
        have = {r["seed"] for r in rows if r["set"] == set_name}
        missing = [s for s in seeds if s not in have]
        if missing:
            rows += cb.benchmark_measures(set_name, missing)
            cb.write_measures(cache, rows)
    rows = [r for r in rows if r["seed"] in seeds]
    evaluation = cb.evaluate(regrets, rows, n_boot=args.n_boot)
    written = [cache, args.out / "completeness.md", args.out / "completeness.csv"]
    written[1].write_text(cb.markdown_table(evaluation))
    cb.write_csv(written[2], evaluation)
    for set_name in sorted({k[0] for k in evaluation}):
        path = args.out / f"completeness_{set_name.replace(' ', '_')}.png"
        cb.completeness_figure(evaluation, set_name, path)
        written.append(path)
    return written


if __name__ == "__main__":
    sys.exit(main())
