"""Colosseum variants against the reference's stored diameter, value norm and gap sum (1e-3 relative).

Two routes, both skipped cleanly without ../shared:

* from the fixtures' own arrays (``custom_mdp`` on ``T``, the reward entries and ``P0``; the reference's episodic
  graph order for the continuous form), for all 41 fixtures now, one stacked vmapped call per family and setting
  (which also checks that padding changes nothing);
* through ``jaxmdp.make`` for the registered families (the others skip until they land): the construction-recorded
  successor/start orders behind the reset quirk and the deterministic flags for every fixture, and all three
  measures end to end for RiverSwim (one compilation per MDP, so only for that small family).
"""

import itertools

import jax
import numpy as np
import pytest

import hardness
import jaxmdp
from jaxmdp import episodic

from conftest import build_reference_mdp, load_reference, reference_index, reference_params
from hardness_helpers import reference_fixture_mdp

RTOL = 1e-3
KEYS = ("diameter", "value_norm", "sum_reciprocals_suboptimality_gaps")


def groups():
    """One stacked batch per family and setting: one compilation each, similar sizes (little padding), and slowly
    converging fixtures (FrozenLake episodic) do not hold the others back."""
    entries = reference_index()
    if not entries:
        return [pytest.param(None, marks=pytest.mark.skip(reason="../shared/reference is not available"))]
    key = lambda e: (e["family"], e["setting"])  # noqa: E731
    return [
        pytest.param(list(g), id=f"{fam}-{setting}")
        for (fam, setting), g in itertools.groupby(sorted(entries, key=key), key=key)
    ]


def colosseum_batch(batch, forms):
    def one(m, cf):
        return (
            hardness.diameter(m, variant="colosseum").value,
            hardness.value_norm(m, variant="colosseum", continuous_form=cf).value,
            hardness.sum_reciprocal_gaps(m, variant="colosseum").value,
        )

    return jax.jit(jax.vmap(one))(batch, forms)


def assert_matches(values, entries):
    for name, got in zip(KEYS, values):
        expected = np.array([e[name] for e in entries])
        np.testing.assert_allclose(np.asarray(got), expected, rtol=RTOL, atol=1e-6, err_msg=name)


@pytest.mark.parametrize("entries", groups())
def test_fixture_arrays_stacked(entries):
    mdps, forms = [], []
    for e in entries:
        m, order = reference_fixture_mdp(load_reference(e))
        mdps.append(m)
        forms.append(episodic.continuous_form(m, order) if order is not None else None)
    batch = jaxmdp.stack(mdps)
    cfs = episodic.stack_continuous_forms(forms) if forms[0] is not None else None
    assert_matches(colosseum_batch(batch, cfs), entries)


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
    assert_matches([np.asarray(v)[None] for v in values], [entry])
