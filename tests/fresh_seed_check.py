"""Re-run every statistical test on fresh seeds and report how often each fails (not part of the default run: pytest
collects ``test_*.py`` only).

    PYTHONPATH=$PWD nice -n 10 python tests/fresh_seed_check.py [--runs 200] [--first 1] [pytest arguments]

Each test marked ``statistical(p=...)`` is called ``--runs`` times in one process, with ``JAXMDP_TEST_SEED`` set to
``first, first + 1, ...`` (tests/stat_checks.py derives each test's keys from it), after its fixtures were set up
once. Prints a table: test, runs, failures, stated false-failure probability, and the seconds spent. A test whose
failures exceed what its stated probability allows (more than zero failures in a few hundred runs, at p <= 1e-6) is
wrong, or its bound is.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from stat_checks import SEED_VARIABLE  # noqa: E402


class FreshSeeds:
    """A pytest plugin: each statistical test's body runs once per fresh seed."""

    def __init__(self, runs: int, first: int, log: str | None = None) -> None:
        self.runs, self.first, self.log = runs, first, log
        self.rows: list[tuple[str, int, int, float, float, str]] = []

    @pytest.hookimpl(tryfirst=True)
    def pytest_pyfunc_call(self, pyfuncitem: pytest.Function):
        mark = pyfuncitem.get_closest_marker("statistical")
        if mark is None:
            return None
        args = {name: pyfuncitem.funcargs[name] for name in pyfuncitem._fixtureinfo.argnames}
        failures, first_message, start = 0, "", time.perf_counter()
        try:
            for i in range(self.runs):
                os.environ[SEED_VARIABLE] = str(self.first + i)
                try:
                    pyfuncitem.obj(**args)
                except AssertionError as err:
                    failures += 1
                    first_message = first_message or f"seed {self.first + i}: {str(err).splitlines()[0][:120]}"
        finally:
            os.environ.pop(SEED_VARIABLE, None)
        self.rows.append((pyfuncitem.nodeid, self.runs, failures, float(mark.kwargs["p"]),
                          time.perf_counter() - start, first_message))
        if self.log is not None:
            with open(self.log, "a") as f:
                f.write(self._line(self.rows[-1]) + "\n")
        return True

    @staticmethod
    def _line(row) -> str:
        nodeid, runs, failures, p, seconds, _ = row
        return f"| {nodeid} | {runs} | {failures} | {p:.1e} | {seconds:.0f} |"

    def table(self) -> str:
        lines = ["| test | runs | failures | stated probability | seconds |", "|---|---|---|---|---|"]
        lines += [self._line(row) for row in self.rows]
        lines += [f"first failure of {nodeid}: {message}" for nodeid, *_, message in self.rows if message]
        return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=200, help="fresh seeds per test (default 200)")
    parser.add_argument("--first", type=int, default=1, help="first fresh seed (default 1)")
    parser.add_argument("--log", help="also append each test's table row to this file as soon as it is done")
    args, pytest_args = parser.parse_known_args(argv)
    plugin = FreshSeeds(args.runs, args.first, args.log)
    code = pytest.main(["-q", "-n0", "-p", "no:cacheprovider", "--timeout=0", "-m", "statistical",
                        *(pytest_args or [str(HERE)])], plugins=[plugin])
    print(plugin.table())
    return int(code) if code not in (0, pytest.ExitCode.NO_TESTS_COLLECTED) else 0


if __name__ == "__main__":
    sys.exit(main())
