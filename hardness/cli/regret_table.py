"""``jaxmdp-regret-table``: the normalised cumulative regret of every tabular agent beside the random agent's on small
RiverSwim and DeepSea (:mod:`hardness.analysis.regret_table`), or with ``--deep`` of every deep agent on small
``state_info`` BlockMDPs (:mod:`hardness.analysis.deep_regret`; the options differ, ``--deep --help`` lists them).

    jaxmdp-regret-table                                   # 100k steps, 20 seeds, RiverSwim 5 and 10, DeepSea 5
    jaxmdp-regret-table --steps 20000 --agents ucrl2 random_continuous --sizes 5
    jaxmdp-regret-table --deep                            # 50 000 steps, 4 seeds
    jaxmdp-regret-table --deep --instances DeepSea-6-episodic --agents dqn_episodic

The runner shards the members over one host device per core (set here, before JAX starts its backend).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from hardness.cli._common import add_cache_flag, compile_report

__all__ = ["build_parser", "main"]


def build_parser(deep: bool = False) -> argparse.ArgumentParser:
    """The tabular table's options, or with ``deep`` the deep table's, plus ``--deep`` and ``--no-compile-cache``."""
    from hardness.analysis import deep_regret, regret_table

    parser = (deep_regret if deep else regret_table).build_parser()
    parser.prog = "jaxmdp-regret-table"
    parser.description = __doc__
    parser.add_argument("--deep", action="store_true",
                        help="the deep agents on BlockMDPs (hardness.analysis.deep_regret) instead of the tabular ones")
    add_cache_flag(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the tabular table, or the deep one with ``--deep`` (module docstring)."""
    from jaxmdp.experiment.devices import use_every_core

    argv = list(sys.argv[1:] if argv is None else argv)
    use_every_core()  # one lockstep loop per core: the runner shards the members over the host devices
    deep = "--deep" in argv
    args = build_parser(deep).parse_args(argv)
    with compile_report(args.no_compile_cache):
        if deep:
            from hardness.analysis import deep_regret

            deep_regret.run_table(args, ["jaxmdp-regret-table", *argv])
        else:
            from hardness.analysis import regret_table

            regret_table.run_table(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
