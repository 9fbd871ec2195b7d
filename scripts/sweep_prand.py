"""Scenario 1 of the hardness analysis, the measures against ``p_rand`` (``jaxmdp-sweep-prand``; see
:mod:`hardness.cli.sweep`). ``python scripts/sweep_prand.py`` is the main job: MiniGridEmpty (size 5) episodic,
p_rand 0..0.5, 3 seeds, tuned PSRL, written to results/sweep_prand/."""

from hardness.cli.sweep import main_prand

if __name__ == "__main__":
    raise SystemExit(main_prand())
