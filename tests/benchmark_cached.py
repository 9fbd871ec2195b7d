"""The reference's cached seed-0 diameter and value norm of the benchmark entries (printed with 4 decimals) against
ours: per setting and size class, a few stacked calls over size buckets (one compilation each), mapped so that each
member stops at its own convergence. The small entries are checked in tests/test_benchmark_suite.py, the larger ones
in the nightly tests of test_benchmark_suite_large_*.py, one file per setting type so that ``--dist loadfile`` can
give them to different workers."""

import jax
import numpy as np
import pytest

import hardness
import jaxmdp
from hardness.benchmark import suite as bs
from jaxmdp import episodic

MAX_STATES_CACHED_CHECK = {"episodic": 150, "continuous": 300}


def cached_entries(setting: str, large: bool) -> list:
    """The entries of ``setting`` with cached values, above (``large``) or up to its size cut."""
    cut = MAX_STATES_CACHED_CHECK[setting.split()[0]]
    return [e for e in bs.entries(setting) if e.family in jaxmdp.families() and (e.n_states > cut) == large
            and e.cached_diameter is not None]


def check_cached(chosen: list, n_buckets: int = 3) -> None:
    """Assert that the colosseum diameter and value norm of the seed-0 MDPs of ``chosen`` match the cache, computed
    per :func:`jaxmdp.size_buckets` group (one compiled ``lax.map`` per group: one stack padded to the largest member
    cost the large episodic entries 2-3x the time)."""
    mdps = [bs.build(e, seed=0) for e in chosen]

    def both(m, cf):
        return (
            hardness.diameter(m, variant="colosseum").value,
            hardness.value_norm(m, variant="colosseum", continuous_form=cf).value,
        )

    run = jax.jit(lambda b, f: jax.lax.map(lambda x: both(*x), (b, f)))
    d, vn = np.full(len(mdps), np.nan), np.full(len(mdps), np.nan)
    for group in jaxmdp.size_buckets(mdps, n_buckets):
        members = [mdps[i] for i in group]
        forms = None
        if members[0].episodic:
            forms = episodic.stack_continuous_forms([episodic.continuous_form(m) for m in members])
        d[group], vn[group] = run(jaxmdp.stack(members), forms)
    # The cache prints 4 decimals.
    np.testing.assert_allclose(d, [e.cached_diameter for e in chosen], rtol=1e-4, atol=6e-5)
    np.testing.assert_allclose(vn, [e.cached_value_norm for e in chosen], rtol=1e-3, atol=6e-5)


def check_setting(setting: str, large: bool) -> None:
    """:func:`check_cached` on :func:`cached_entries`; skips when there are none."""
    chosen = cached_entries(setting, large)
    if not chosen:
        pytest.skip("no cached entry of this size in this setting")
    check_cached(chosen)


def large_entries_test(kind: str):
    """The slow test of the entries above the size cut in the settings of type ``kind`` (episodic, continuous)."""

    @pytest.mark.nightly
    @pytest.mark.parametrize("setting", [s for s in bs.SETTINGS if s.startswith(kind)])
    def test_cached_seed0_diameter_and_value_norm_large(setting):
        check_setting(setting, large=True)

    return test_cached_seed0_diameter_and_value_norm_large
