"""Scenario 1 of the hardness analysis (paper §3.2, App. D): the hardness measures against ``p_rand``.

One base MDP per seed; every value of ``p_rand`` is the jittable kernel transform of it (``jaxmdp.apply_p_rand``), so
each seed's whole grid is one batched call of ``hardness.measures``; beside the measures, the regret of the tuned
near-optimal agent (``hardness.analysis.near_optimal``: PSRL episodic, UCRL2 continuous; ``--agent-steps 0`` leaves it
out). Writes ``results/sweep_prand/`` (CSV of raw and normalised measures and regrets per (seed, p_rand), the settings
as JSON, a PNG figure).

    python scripts/sweep_prand.py          # MiniGridEmpty (size 5) episodic, p_rand 0..0.5, 3 seeds, tuned PSRL
    python scripts/sweep_prand.py --family RiverSwim --setting continuous --param size=20 --seeds 0 1 2
    python scripts/sweep_prand.py --values 0 0.1 0.2 --variant colosseum --resume
"""

import sys

from hardness.analysis.sweep_cli import main

if __name__ == "__main__":
    sys.exit(main(1, description=__doc__, default_out="results/sweep_prand", entry_point=True))
