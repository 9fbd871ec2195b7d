"""The reference's cached seed-0 diameter and value norm of the continuous benchmark entries above the size cut of
tests/benchmark_cached.py (slow; CI runs them). A file of its own so that ``--dist loadfile`` can run it beside
the other setting type's."""

import pytest

from benchmark_cached import check_setting
from hardness.benchmark import suite as bs


@pytest.mark.slow
@pytest.mark.parametrize("setting", [s for s in bs.SETTINGS if s.startswith("continuous")])
def test_cached_seed0_diameter_and_value_norm_large(setting):
    check_setting(setting, large=True)
