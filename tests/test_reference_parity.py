"""Parity with the arrays and values exported from the reference package (../shared/reference/colosseum).

Skipped cleanly when the shared folder is absent.
"""

import jax
import numpy as np
import pytest

import jaxmdp

from conftest import build_reference_mdp, load_reference, reference_params

_reference_values = jax.jit(jaxmdp.reference_values, static_argnums=1)

# Fixtures with randomize_actions=True whose permutations the engine already reproduces exactly.


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
    values = _reference_values(m.strip(), "colosseum")
    for name in ("optimal", "worst", "random"):
        np.testing.assert_allclose(
            float(getattr(values, name)), entry[f"{name}_value"], rtol=1e-4, atol=1e-6, err_msg=name
        )
    assert jaxmdp.communication_class(m).name == entry["communication_class"]
