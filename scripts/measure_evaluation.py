"""Rank correlations of the hardness measures with a near-optimal agent's regret (``jaxmdp-measure-evaluation``; see
:mod:`hardness.cli.measure_evaluation`)."""

from hardness.cli.measure_evaluation import main

if __name__ == "__main__":
    raise SystemExit(main())
