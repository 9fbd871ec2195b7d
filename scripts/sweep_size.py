"""Scenarios 3 and 4 of the hardness analysis (paper §3.2, App. D): the hardness measures against the MDP's size.

Every MDP of the grid is built from scratch, all are padded to common shapes (``jaxmdp.stack``; padding changes no
measure) and each seed's sizes are one batched call. ``--scenario 4`` sets ``p_rand = 0.1``. The figure's x axis is
the number of states (mean over seeds where it depends on the seed). Writes ``results/sweep_size/``.

    python scripts/sweep_size.py                                    # scenario 3, MiniGridEmpty episodic, sizes 4..10
    python scripts/sweep_size.py --scenario 4 --family DeepSea --setting continuous --values 5 10 15 20
"""

import sys

from hardness.analysis.sweep_cli import main

if __name__ == "__main__":
    sys.exit(main(3, description=__doc__, default_out="results/sweep_size", scenario_choices=(3, 4), entry_point=True))
