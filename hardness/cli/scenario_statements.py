"""``jaxmdp-scenario-statements``: the paper's statements about how the measures move in its scenarios (§3.2,
App. D), each checked under ``variant="paper"`` and ``variant="colosseum"`` (:mod:`hardness.analysis.statements`).

Computes the measures of scenarios 1-4 on the paper's five families in both settings under both variants (no agents;
the default grids of :mod:`hardness.analysis.scenarios`, seeds ``0..N-1``), grid by grid into
``<out>/scenario_measures.csv`` (a second run reuses the grids already there, whatever their seeds), then writes
``<out>/statements.md`` (one row per statement: the trend under each variant and a verdict), ``statements.csv``,
``cases.csv`` (every case's reading) and ``statements_<setting>.png`` (the normalised curves, both variants).

    jaxmdp-scenario-statements --out results/scenario_statements
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from hardness.cli._common import add_cache_flag, compile_report

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command's options (module docstring)."""
    from hardness.analysis import statements as st

    parser = argparse.ArgumentParser(prog="jaxmdp-scenario-statements", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("results/scenario_statements"), help="default %(default)s")
    parser.add_argument("--seeds", type=int, default=3,
                        help="seeds 0..N-1 of every grid not yet in the table (default %(default)s)")
    parser.add_argument("--families", nargs="+", default=list(st.FAMILIES), help="default: the paper's five")
    parser.add_argument("--quiet", action="store_true", help="do not list the files written on stdout")
    add_cache_flag(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Compute the measures (or reuse them), check the statements and write the outputs (module docstring)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1; got {args.seeds}")
    with compile_report(args.no_compile_cache):
        written = run(args)
    if not args.quiet:
        print("\n".join(map(str, written)))
    return 0


def run(args: argparse.Namespace) -> list[Path]:
    """Compute what is missing from ``<out>/scenario_measures.csv``, then write the tables and figures."""
    from hardness.analysis import statements as st

    args.out.mkdir(parents=True, exist_ok=True)
    table = args.out / "scenario_measures.csv"
    seeds = list(range(args.seeds))
    rows = st.read_measures(table) if table.exists() else []
    done = {(r["family"], r["setting"], r["scenario"], r["variant"]) for r in rows}

    def save(key, new):
        rows.extend(new)
        st.write_measures(table, rows)
        if not args.quiet:
            print(f"computed {key}", file=sys.stderr, flush=True)

    st.collect(args.families, seeds=seeds, skip=done, on_grid=save)
    return [table, *write_outputs(rows, args.out)]


def write_outputs(rows, out: Path) -> list[Path]:
    """The statement table, its CSVs and the figures of the measures ``rows`` into ``out``."""
    from hardness.analysis import statements as st

    cv = st.curves(rows)
    results = st.check(cv)
    written = [out / "statements.md", out / "statements.csv", out / "cases.csv"]
    written[0].write_text(st.markdown_table(results))
    st.write_results(written[1], written[2], results)
    for setting in st.SETTINGS:
        path = out / f"statements_{setting}.png"
        st.statements_figure(cv, setting, path)
        written.append(path)
    return written


if __name__ == "__main__":
    sys.exit(main())
