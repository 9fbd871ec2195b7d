"""The paper's statements about the measures in its scenarios, under both variants (``jaxmdp-scenario-statements``;
see :mod:`hardness.cli.scenario_statements`)."""

from hardness.cli.scenario_statements import main

if __name__ == "__main__":
    raise SystemExit(main())
