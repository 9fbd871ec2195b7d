"""The benchmark suite data (docs/benchmark.md §3) and, for the registered families, the reference's cached seed-0
diameter and value norm of each entry (printed with 4 decimals)."""

import collections

import jax
import numpy as np
import pytest

import hardness
import jaxmdp
from hardness.benchmark import suite as bs
from jaxmdp import episodic

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


# Cached-value checks run as one stacked call per setting and size class (one compilation each), mapped so that each
# member stops at its own convergence. Every cached entry is checked: the small ones in the quick test, the larger
# ones (all 40 continuous entries up to 948 states took ~2 min) in the slow one, which CI runs too.
MAX_STATES_CACHED_CHECK = {"episodic": 150, "continuous": 300}


def _cached_entries(setting: str, large: bool) -> list:
    cut = MAX_STATES_CACHED_CHECK[setting.split()[0]]
    return [e for e in bs.entries(setting) if e.family in jaxmdp.families() and (e.n_states > cut) == large
            and e.cached_diameter is not None]


def _check_cached(chosen: list) -> None:
    mdps = [bs.build(e, seed=0) for e in chosen]
    batch = jaxmdp.stack(mdps)
    forms = episodic.stack_continuous_forms([episodic.continuous_form(m) for m in mdps]) if mdps[0].episodic else None

    def both(m, cf):
        return (
            hardness.diameter(m, variant="colosseum").value,
            hardness.value_norm(m, variant="colosseum", continuous_form=cf).value,
        )

    d, vn = jax.jit(lambda b, f: jax.lax.map(lambda x: both(*x), (b, f)))(batch, forms)
    # The cache prints 4 decimals.
    np.testing.assert_allclose(d, [e.cached_diameter for e in chosen], rtol=1e-4, atol=6e-5)
    np.testing.assert_allclose(vn, [e.cached_value_norm for e in chosen], rtol=1e-3, atol=6e-5)


@pytest.mark.parametrize(
    "setting, large",
    [(setting, False) for setting in bs.SETTINGS]
    + [pytest.param(setting, True, marks=pytest.mark.slow) for setting in bs.SETTINGS],
)
def test_cached_seed0_diameter_and_value_norm(setting, large):
    chosen = _cached_entries(setting, large)
    if not chosen:
        pytest.skip("no cached entry of this size in this setting")
    _check_cached(chosen)


def test_every_cached_value_is_checked():
    for setting in bs.SETTINGS:
        cached = [e for e in bs.entries(setting) if e.cached_diameter is not None]
        assert all(e.family in jaxmdp.families() for e in cached)
        assert len(_cached_entries(setting, False)) + len(_cached_entries(setting, True)) == len(cached)
