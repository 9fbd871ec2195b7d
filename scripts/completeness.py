"""The completeness test on the benchmark: rank correlations of the measures with the tuned agents' regret
(``jaxmdp-completeness``; see :mod:`hardness.cli.completeness`)."""

from hardness.cli.completeness import main

if __name__ == "__main__":
    raise SystemExit(main())
