"""The regret table of the tabular agents, or with ``--deep`` of the deep agents (``jaxmdp-regret-table``; see
:mod:`hardness.cli.regret_table`)."""

from hardness.cli.regret_table import main

if __name__ == "__main__":
    raise SystemExit(main())
