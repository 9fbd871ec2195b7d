"""Colosseum variants of the MDPs built by ``jaxmdp.make`` for every reference fixture against the reference's stored
diameter, value norm and gap sum (1e-3 relative), with the construction-recorded orders and deterministic flags
behind them; the route through the fixtures' own arrays is tests/test_hardness_reference.py. Skipped cleanly without
../shared."""

import numpy as np
import pytest

import hardness
import jaxmdp
from jaxmdp import episodic

from conftest import build_reference_mdp, load_reference, reference_params
from hardness_helpers import assert_matches_reference


@pytest.fixture(scope="module")
def built():
    cache = {}

    def get(entry):
        if entry["family"] not in jaxmdp.families():
            pytest.skip(f"family {entry['family']} is not implemented yet")
        if entry["id"] not in cache:
            cache[entry["id"]] = build_reference_mdp(entry)
        return cache[entry["id"]]

    return get


@pytest.mark.parametrize("entry", reference_params())
def test_family_built_episodic_order_and_flags(entry, built):
    """What the family path adds to the fixture-array route: the construction-recorded successor and start orders
    give the reference's episodic-graph order (hence its continuous form and reset quirk), and the deterministic
    flags of the value-norm shortcut. (The arrays themselves are compared in test_reference_parity.)"""
    m = built(entry)
    ref = load_reference(entry)
    assert bool(hardness.deterministic_base(m)) == (
        bool(ref["all_transitions_deterministic"]) and bool(ref["all_rewards_deterministic"])
    )
    if entry["setting"] == "episodic":
        np.testing.assert_array_equal(episodic.episodic_graph_order(m), ref["episodic_graph_nodes"])


@pytest.mark.slow
@pytest.mark.parametrize("entry", reference_params())
def test_family_built_end_to_end(entry, built):
    # Every fixture, built by jaxmdp.make (test_family_built_episodic_order_and_flags checks make builds them all).
    m = built(entry)
    values = (
        hardness.diameter(m, variant="colosseum").value,
        hardness.value_norm(m, variant="colosseum").value,
        hardness.sum_reciprocal_gaps(m, variant="colosseum").value,
    )
    assert_matches_reference([np.asarray(v)[None] for v in values], [entry])
