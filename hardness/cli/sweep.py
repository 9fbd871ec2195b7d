"""``jaxmdp-sweep``: one scenario of the hardness analysis (paper §3.2, App. D), the hardness measures against a swept
parameter, beside the regret of a tuned near-optimal agent (:mod:`hardness.analysis.sweep_cli`).

Scenario 1 sweeps ``p_rand`` and 2 ``p_lazy`` (one base MDP per seed, every value the jittable kernel transform of it:
``jaxmdp.apply_p_rand``, ``jaxmdp.apply_p_lazy``; DeepSea has no lazy mechanic and is refused by 2); 3 sweeps the
size (every MDP built from scratch, padded to common shapes with ``jaxmdp.stack``) and 4 the size with
``p_rand = 0.1``. The figure's x axis is the swept value (3, 4: the number of states, mean over seeds). Writes
``<out>/scenario<k>_<family>_<setting>.{csv,json,png}``, by default in ``results/sweep_prand``, ``sweep_plazy`` or
``sweep_size``.

    jaxmdp-sweep-prand                  # MiniGridEmpty (size 5) episodic, p_rand 0..0.5, 3 seeds, tuned PSRL
    jaxmdp-sweep --scenario 1 --family RiverSwim --setting continuous --param size=20 --seeds 3
    jaxmdp-sweep --scenario 1 --values 0 0.1 0.2 --variant colosseum --resume
    jaxmdp-sweep --scenario 2 --family SimpleGrid --setting continuous --param size=10
    jaxmdp-sweep --scenario 3           # MiniGridEmpty episodic, sizes 4..10
    jaxmdp-sweep --scenario 4 --family DeepSea --setting continuous --values 5 10 15 20
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from hardness.analysis import sweep_cli

__all__ = ["main", "main_prand"]


def main(argv: Sequence[str] | None = None) -> int:
    """``jaxmdp-sweep [--scenario {1,2,3,4}] ...`` (module docstring; ``--help`` lists the options)."""
    return sweep_cli.main(1, argv, description=__doc__, default_out=None, scenario_choices=(1, 2, 3, 4),
                          entry_point=True)


def main_prand(argv: Sequence[str] | None = None) -> int:
    """``jaxmdp-sweep-prand``: scenario 1 (``p_rand``), written to ``results/sweep_prand`` by default."""
    return sweep_cli.main(1, argv, description=__doc__, default_out=sweep_cli.DEFAULT_OUTS[1], entry_point=True)


if __name__ == "__main__":
    sys.exit(main())
