"""The benchmark suite data (docs/benchmark.md §3) and, for the registered families, the reference's cached seed-0
diameter and value norm of each entry (printed with 4 decimals)."""

import collections

import pytest

from conftest import nightly_beyond

import jaxmdp
from benchmark_cached import cached_entries, check_setting
from hardness.benchmark import suite as bs

# Paper Table 1 / docs/benchmark.md §3: MDPs per setting and family.
COUNTS = {
    "episodic ergodic": dict(DeepSea=2, FrozenLake=1, MiniGridEmpty=7, MiniGridRooms=3, RiverSwim=2, SimpleGrid=3, Taxi=2),
    "episodic communicating": dict(DeepSea=2, FrozenLake=1, MiniGridEmpty=5, MiniGridRooms=4, RiverSwim=2, SimpleGrid=4, Taxi=2),
    "continuous ergodic": dict(DeepSea=1, FrozenLake=1, MiniGridEmpty=8, MiniGridRooms=2, RiverSwim=4, SimpleGrid=3, Taxi=1),
    "continuous communicating": dict(DeepSea=3, FrozenLake=2, MiniGridEmpty=5, MiniGridRooms=3, RiverSwim=2, SimpleGrid=4, Taxi=1),
}


def test_eighty_entries_with_table_counts():
    assert len(bs.BENCHMARK) == 80
    for setting in bs.SETTINGS:
        got = collections.Counter(e.family for e in bs.entries(setting))
        assert dict(got) == COUNTS[setting]
    assert len({e.name for e in bs.BENCHMARK}) == 80
    assert all((e.H is None) != e.episodic for e in bs.BENCHMARK)


def test_episodic_river_swim_distributions_are_the_printed_ones():
    e = next(e for e in bs.entries("episodic ergodic", "RiverSwim") if e.scope == "prms_0")
    kw = e.kwargs()
    assert (kw["optimal_distribution"].a, kw["optimal_distribution"].b) == (0.01, 0.11)
    assert (kw["sub_optimal_distribution"].a, kw["sub_optimal_distribution"].b) == (2.4, 24.0)
    assert (kw["other_distribution"].a, kw["other_distribution"].b) == (2.4, 249.0)
    assert "sub=Beta(2.4,24.0)" in e.effective_distributions
    # The continuous ones keep the family defaults.
    assert not next(iter(bs.entries("continuous ergodic", "RiverSwim"))).overrides


def test_unknown_setting():
    with pytest.raises(ValueError, match="setting"):
        bs.entries("episodic")


def registered_entries():
    return [pytest.param(e, id=e.name) for e in bs.BENCHMARK]


@pytest.mark.parametrize("entry", registered_entries())
def test_built_entry_structure(entry):
    if entry.family not in jaxmdp.families():
        pytest.skip(f"family {entry.family} is not implemented yet")
    m = bs.build(entry, seed=0)
    assert m.n_states == entry.n_states
    assert m.H == entry.H
    assert jaxmdp.communication_class(m).name == entry.communication_class


# Cached-value checks (tests/benchmark_cached.py): the small entries here (the default profile: one episodic and one
# continuous setting, of each communication class one), the larger ones in test_benchmark_suite_large_episodic.py and
# test_benchmark_suite_large_continuous.py (nightly).
@pytest.mark.nightly  # the committed cache; by default: the measures' reference parity
@pytest.mark.parametrize("setting", nightly_beyond(bs.SETTINGS, lambda s: s in ("episodic ergodic",
                                                                             "continuous communicating")))
def test_cached_seed0_diameter_and_value_norm(setting):
    check_setting(setting, large=False)


def test_every_cached_value_is_checked():
    for setting in bs.SETTINGS:
        cached = [e for e in bs.entries(setting) if e.cached_diameter is not None]
        assert all(e.family in jaxmdp.families() for e in cached)
        assert len(cached_entries(setting, False)) + len(cached_entries(setting, True)) == len(cached)
