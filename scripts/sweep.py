"""One scenario of the hardness analysis, ``--scenario {1,2,3,4}`` (``jaxmdp-sweep``; see :mod:`hardness.cli.sweep`)."""

from hardness.cli.sweep import main

if __name__ == "__main__":
    raise SystemExit(main())
