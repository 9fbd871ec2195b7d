"""The reference's cached seed-0 diameter and value norm of the episodic benchmark entries above the size cut of
tests/benchmark_cached.py (nightly profile). A file of its own so that ``--dist loadfile`` can run it beside
the other setting type's."""

from benchmark_cached import large_entries_test

test_cached_seed0_diameter_and_value_norm_large = large_entries_test("episodic")
