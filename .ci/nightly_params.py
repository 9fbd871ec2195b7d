"""Write ``tests/nightly_params.txt``: the parameter sets that the default test profile leaves to the nightly one.

The rule (docs/testing.md, "Profiles"): every test function runs in the default profile; of a parametrised one, its
first parameter set (in collection order) always, and each further set that takes less than ``--seconds`` (setup,
call and teardown together) in the timing given; the longer further sets run nightly. A set the timing does not cover
(the list had it nightly, so the default run did not time it) stays listed. Input: the output of a default profile
run with ``--durations=0`` (``pytest -q --durations=0 > durations.log``)::

    python .ci/nightly_params.py durations.log [--seconds 1] > tests/nightly_params.txt
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
OUTPUT = REPO / "tests" / "nightly_params.txt"
_DURATION = re.compile(r"^\s*([0-9.]+)s\s+(setup|call|teardown)\s+(\S.*\S)\s*$")


def durations(log: Path) -> dict[str, float]:
    """Seconds per node id (its setup, call and teardown summed) from pytest's ``--durations`` report."""
    out: dict[str, float] = collections.defaultdict(float)
    for line in log.read_text().splitlines():
        if m := _DURATION.match(line):
            out[m.group(3)] += float(m.group(1))
    return out


def collected() -> list[str]:
    """The default profile's node ids, in collection order, with no nightly list applied."""
    listing = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-n", "0", "-p",
                              "no:cacheprovider"], cwd=REPO, capture_output=True, text=True, check=True,
                             env={**os.environ, "JAXMDP_NIGHTLY_PARAMS": "off"}).stdout
    return [line.strip() for line in listing.splitlines() if "::" in line and not line.startswith(" ")]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("log", type=Path, help="a default profile run's --durations=0 output")
    parser.add_argument("--seconds", type=float, default=1.0, help="longest further set kept (%(default)s s)")
    args = parser.parse_args(argv)
    seconds = durations(args.log)
    listed = ({line.strip() for line in OUTPUT.read_text().splitlines() if line.strip() and not line.startswith("#")}
              if OUTPUT.exists() else set())
    first: set[str] = set()
    moved = []
    for node in collected():
        if "[" not in node:
            continue
        function = node.split("[", 1)[0]
        if function not in first:
            first.add(function)
        elif seconds[node] >= args.seconds if node in seconds else node in listed:
            moved.append(node)
    print("# Parameter sets the default profile leaves to the nightly one (.ci/nightly_params.py: each test function")
    print(f"# keeps its first set and every further set under {args.seconds:g} s; docs/testing.md, \"Profiles\").")
    print("\n".join(moved))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
