"""Colosseum variants against the reference's stored diameter, value norm and gap sum (1e-3 relative).

Two routes, both skipped cleanly without ../shared (the second in tests/test_hardness_reference_built.py, a file of
its own so that ``--dist loadfile`` can run the two on different workers):

* from the fixtures' own arrays (``custom_mdp`` on ``T``, the reward entries and ``P0``; the reference's episodic
  graph order for the continuous form), for all 41 fixtures now, one stacked mapped call per family and setting
  (which also checks that padding changes nothing);
* through ``jaxmdp.make`` for the registered families (the others skip until they land): the construction-recorded
  successor/start orders behind the reset quirk and the deterministic flags for every fixture, and all three
  measures end to end for every fixture (one hardness.measures_many call).
"""

import itertools

import jax
import pytest

import hardness
import jaxmdp
from jaxmdp import episodic

from conftest import load_reference, reference_index
from hardness_helpers import assert_matches_reference, reference_fixture_mdp


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
    # The three public functions one by one, not hardness.map_measures: measures() shares the optimal values between
    # the value norm and the gap sum, and the built-fixture route (test_hardness_reference_built.py) goes through it,
    # so each route checks a different path against the reference.
    def one(m, cf):
        return (
            hardness.diameter(m, variant="colosseum").value,
            hardness.value_norm(m, variant="colosseum", continuous_form=cf).value,
            hardness.sum_reciprocal_gaps(m, variant="colosseum").value,
        )

    # lax.map over the padded stack, not vmap: vmap over members is tested in tests/test_hardness_measures.py, and in
    # lockstep the colosseum diameter of the Taxi stack took 30 s against 6 s mapped (batched gathers on a CPU).
    return jax.jit(lambda b, f: jax.lax.map(lambda x: one(*x), (b, f)))(batch, forms)


@pytest.mark.parametrize("entries", groups())
def test_fixture_arrays_stacked(entries):
    mdps, forms = [], []
    for e in entries:
        m, order = reference_fixture_mdp(load_reference(e))
        mdps.append(m)
        forms.append(episodic.continuous_form(m, order) if order is not None else None)
    batch = jaxmdp.stack(mdps)
    cfs = episodic.stack_continuous_forms(forms) if forms[0] is not None else None
    assert_matches_reference(colosseum_batch(batch, cfs), entries)
