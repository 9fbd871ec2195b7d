"""``jaxmdp-measure-evaluation``: rank correlation of every hardness measure with the tuned near-optimal agent's regret
(paper §2.3's completeness).

Reads the tables of scenario sweeps (``jaxmdp-sweep``, run with the agent: ``--agent-steps`` > 0) and writes, for
each, Spearman's rho and Kendall's tau-b between each measure and the agent's per-step normalised cumulative regret,
with 95% bootstrap intervals over seeds (:mod:`hardness.analysis.measure_evaluation`): ``<out>/measure_evaluation.md``
(a Markdown table), ``.csv`` and ``.png``. Unless ``--no-extra``, the mixing time and the distribution mismatch
coefficient are computed on the same MDPs and evaluated too.

    jaxmdp-measure-evaluation results/sweep_prand/scenario1_RiverSwim_continuous.csv \\
        results/sweep_plazy/scenario2_RiverSwim_continuous.csv --out results/measure_evaluation
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections.abc import Sequence
from pathlib import Path

from hardness.cli._common import add_cache_flag, compile_report

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command's options (module docstring)."""
    from hardness.analysis import measure_evaluation as me

    parser = argparse.ArgumentParser(prog="jaxmdp-measure-evaluation", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("tables", type=Path, nargs="+", help="CSV tables written by jaxmdp-sweep")
    parser.add_argument("--out", type=Path, default=Path("results/measure_evaluation"), help="default %(default)s")
    parser.add_argument("--regret", default=me.REGRET_COLUMN, help="regret column (default %(default)s)")
    parser.add_argument("--n-boot", type=int, default=1000, help="bootstrap resamples (default %(default)s)")
    parser.add_argument("--no-extra", action="store_true", help="skip the mixing time and distribution mismatch")
    parser.add_argument("--quiet", action="store_true", help="do not list the files written on stdout")
    add_cache_flag(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Evaluate the measures on the given sweep tables (module docstring)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    with compile_report(args.no_compile_cache):
        evaluate(args, parser)
    return 0


def evaluate(args: argparse.Namespace, parser: argparse.ArgumentParser) -> list[Path]:
    """Write the correlation table, CSV and figure of the parsed ``args``; returns the paths written."""
    from hardness.analysis import measure_evaluation as me
    from hardness.analysis.scenarios import MEASURES

    results = {}
    for path in args.tables:
        if not path.exists():
            parser.error(f"no such table: {path}")
        rows, config = me.read_sweep(path)
        if not rows or args.regret not in rows[0]:
            parser.error(f"{path} has no {args.regret!r} column: run the sweep with --agent-steps > 0")
        measures = list(MEASURES)
        if not args.no_extra and config:
            for name, values in me.extra_measures(rows, config).items():
                for row, v in zip(rows, values):
                    row[name] = float(v)
            measures += list(me.EXTRA_MEASURES)
        name = f"{config.get('scenario', '?')}: {config.get('family', '')} {config.get('setting', '')} " \
               f"({config.get('parameter', '')})"
        results[name] = me.correlations(rows, measures, regret=args.regret, n_boot=args.n_boot)
    args.out.mkdir(parents=True, exist_ok=True)
    md = args.out / "measure_evaluation.md"
    md.write_text(me.markdown_table(results))
    with (args.out / "measure_evaluation.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["scenario", "measure", "spearman", "spearman_lo", "spearman_hi", "kendall", "kendall_lo",
                    "kendall_hi", "n_rows"])
        for name, corrs in results.items():
            for c in corrs:
                w.writerow([name, c.measure, c.spearman, *c.spearman_ci, c.kendall, *c.kendall_ci, c.n_rows])
    me.evaluation_figure(results, args.out / "measure_evaluation.png")
    written = [args.out / p for p in ("measure_evaluation.md", "measure_evaluation.csv", "measure_evaluation.png")]
    if not args.quiet:
        print("\n".join(map(str, written)))
    return written


if __name__ == "__main__":
    sys.exit(main())
