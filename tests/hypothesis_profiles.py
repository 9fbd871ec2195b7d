"""Hypothesis settings of the property tests (tests/test_properties_*.py), selected by ``$HYPOTHESIS_PROFILE``.

* ``ci`` (default): ``derandomize=True``, so a run draws the same examples every time (CI cannot fail on a draw that
  a re-run does not repeat), no example database (nothing written into the checkout), no deadline (the first example
  of a shape pays XLA's compilation). Each test names its own number of examples with :func:`examples`, sized so that
  the whole set stays within the suite's budget (docs/testing.md, Property-based tests).
* ``nightly``: random draws (a new seed every run, printed with a failure together with the falsifying example) and
  :data:`NIGHTLY_FACTOR` times the examples: ``HYPOTHESIS_PROFILE=nightly pytest -n 0 tests/test_properties_*.py``.

Importing this module registers both profiles and loads the selected one; the test modules import it, not
``conftest.py``, so that the rest of the suite runs without Hypothesis installed.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

#: How many times the CI examples a nightly run draws.
NIGHTLY_FACTOR = 25

_COMMON = dict(
    deadline=None,
    database=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

settings.register_profile("ci", derandomize=True, **_COMMON)
settings.register_profile("nightly", derandomize=False, **_COMMON)

PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "ci")
if PROFILE not in ("ci", "nightly"):
    raise ValueError(f"HYPOTHESIS_PROFILE must be 'ci' or 'nightly'; got {PROFILE!r}")
settings.load_profile(PROFILE)


def examples(ci: int) -> int:
    """The number of examples of a test that draws ``ci`` of them in the CI profile."""
    return ci * NIGHTLY_FACTOR if PROFILE == "nightly" else ci
