"""Colosseum variants of the MDPs built by ``jaxmdp.make`` for every reference fixture against the reference's stored
diameter, value norm and gap sum (1e-3 relative), with the construction-recorded orders and deterministic flags
behind them; the route through the fixtures' own arrays is tests/test_hardness_reference.py. Skipped cleanly without
../shared.

The end-to-end values come from one :func:`hardness.measures_many` call over every built fixture (the route of the
benchmark's 80-MDP hardness call): a compilation per size bucket instead of one per fixture shape and measure.
:func:`hardness.measures_many` equals the per-MDP functions member by member (tests/test_hardness_measures.py), so
the single-MDP functions are covered there and in tests/test_hardness_reference.py."""

import jax
import numpy as np
import pytest

import hardness
import jaxmdp
from jaxmdp import episodic

from conftest import build_reference_mdp, load_reference, reference_index, reference_params
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


@pytest.fixture(scope="module")
def built_measures(built, request):
    """Fixture id -> (diameter, value norm, gap sum) of the colosseum variant, for every registered family's
    fixture that this session's tests ask for (the default profile: the first of each family and setting), from one
    ``measures_many`` call. Five size buckets rather than the default eight: fewer compilations for a little more
    padding (51 against 62 s on a 2-core CPU for all fixtures; two buckets took 111 s)."""
    wanted = {item.callspec.params["entry"]["id"] for item in request.session.items
              if item.originalname == "test_family_built_end_to_end" and item.callspec.params["entry"] is not None}
    entries = [e for e in reference_index() if e["family"] in jaxmdp.families() and e["id"] in wanted]
    out = hardness.measures_many([built(e) for e in entries], variant="colosseum", n_buckets=5)
    results = (out.diameter, out.value_norm, out.sum_reciprocal_gaps)
    values = [np.asarray(r.value) for r in results]
    converged = np.stack([np.asarray(r.converged) for r in results], axis=1).all(axis=1)
    return {e["id"]: (tuple(v[i] for v in values), bool(converged[i])) for i, e in enumerate(entries)}


@pytest.mark.parametrize("entry", reference_params())
def test_family_built_episodic_order_and_flags(entry, built):
    """What the family path adds to the fixture-array route: the construction-recorded successor and start orders
    give the reference's episodic-graph order (hence its continuous form and reset quirk), and the deterministic
    flags of the value-norm shortcut. (The arrays themselves are compared in test_reference_parity.)"""
    m = built(entry)
    ref = load_reference(entry)
    # Jitted: one compilation per fixture shape instead of one per primitive.
    assert bool(jax.jit(hardness.deterministic_base)(m)) == (
        bool(ref["all_transitions_deterministic"]) and bool(ref["all_rewards_deterministic"])
    )
    if entry["setting"] == "episodic":
        np.testing.assert_array_equal(episodic.episodic_graph_order(m), ref["episodic_graph_nodes"])


@pytest.mark.parametrize("entry", reference_params(every=False))
def test_family_built_end_to_end(entry, built, built_measures):
    # Every fixture, built by jaxmdp.make (test_family_built_episodic_order_and_flags checks make builds them all).
    built(entry)  # skips an unregistered family
    values, converged = built_measures[entry["id"]]
    assert converged
    assert_matches_reference([np.asarray(v)[None] for v in values], [entry])
