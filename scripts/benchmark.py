"""The Colosseum benchmark: ``run``, ``report`` and ``tune`` (``jaxmdp-benchmark``; see
:mod:`hardness.cli.benchmark`)."""

from hardness.cli.benchmark import main

if __name__ == "__main__":
    raise SystemExit(main())
