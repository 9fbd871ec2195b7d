"""Parity with the arrays and values exported from the reference package (../shared/reference/colosseum).

Skipped cleanly when the shared folder is absent.
"""

import numpy as np
import pytest

import jaxmdp

from conftest import build_reference_mdp, load_reference, reference_params

# The values are computed on the MDP padded to a few shapes (the 41 fixtures have 41 shapes; one program per shape
# took 163 s of compilation): padding changes no value (padded states and actions are masked out, steps from the
# horizon on are worth zero), which the runner relies on for its stacked batches, so this also checks that.
_STATE_BUCKETS = (32, 64, 128, 256, 512)


def _padded(m: jaxmdp.MDP) -> jaxmdp.MDP:
    """``m`` padded to the next of :data:`_STATE_BUCKETS` states, 6 actions, 9 successors, 32 steps, 4 or 256 starts."""
    S = next(b for b in _STATE_BUCKETS if b >= m.n_states)
    assert m.n_actions <= 6 and m.succ.shape[-1] <= 9 and (m.H or 0) <= 32 and m.max_starts <= 256, "a new bucket"
    return jaxmdp.pad(m.strip(), S, 6, 9, 32 if m.episodic else None, 4 if m.max_starts <= 4 else 256)


@pytest.fixture(scope="module")
def built():
    cache = {}

    def get(entry):
        if entry["id"] not in cache:
            cache[entry["id"]] = build_reference_mdp(entry)
        return cache[entry["id"]]

    return get


@pytest.mark.parametrize("entry", reference_params())
def test_arrays_and_state_order(entry, built):
    ref = load_reference(entry)
    m = built(entry)
    assert m.n_states == entry["n_states"] and m.n_actions == entry["n_actions"]
    assert list(m.info.node_labels) == [str(x) for x in ref["node_labels"]]
    np.testing.assert_allclose(m.T, ref["T"], atol=1e-6)
    np.testing.assert_allclose(m.R, ref["R"], atol=1e-6)
    np.testing.assert_allclose(m.P0, ref["P0"], atol=1e-6)
    if entry["setting"] == "episodic":
        assert m.H == int(ref["H"])
    else:
        assert m.H is None


@pytest.mark.parametrize("entry", reference_params())
def test_reference_values_and_class(entry, built):
    m = built(entry)
    values = jaxmdp.reference_values(_padded(m), "colosseum")
    for name in ("optimal", "worst", "random"):
        np.testing.assert_allclose(
            float(getattr(values, name)), entry[f"{name}_value"], rtol=1e-4, atol=1e-6, err_msg=name
        )
    assert jaxmdp.communication_class(m).name == entry["communication_class"]
