"""Scenario 2 of the hardness analysis (paper §3.2, App. D): the hardness measures against ``p_lazy``.

One base MDP per seed; every value of ``p_lazy`` is the jittable kernel transform of it (``jaxmdp.apply_p_lazy``).
Writes ``results/sweep_plazy/``. DeepSea has no lazy mechanic and is refused.

    python scripts/sweep_plazy.py                                   # MiniGridEmpty (size 5) episodic, p_lazy 0..0.5, 3 seeds, tuned PSRL
    python scripts/sweep_plazy.py --family SimpleGrid --setting continuous --param size=10
"""

import sys

from hardness.analysis.sweep_cli import main

if __name__ == "__main__":
    sys.exit(main(2, description=__doc__, default_out="results/sweep_plazy", entry_point=True))
