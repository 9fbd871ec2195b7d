"""Parity with the arrays and values exported from the reference package (../shared/reference/colosseum).

Skipped cleanly when the shared folder is absent.
"""

import numpy as np
import pytest

import jaxmdp

from conftest import build_reference_mdp, load_reference, reference_index, reference_params

# The values are computed on each MDP padded to the shape of its size bucket (jaxmdp.size_buckets, as the runner and
# the benchmark stack MDPs; the 41 fixtures have 41 shapes, one compiled program each took 163 s): padding changes no
# value (padded states and actions are masked out, steps from the horizon on are worth zero), which the stacked
# batches rely on, so this also checks that.
N_BUCKETS = 6


def _padded_shapes(entries: list[dict], build) -> dict[str, tuple]:
    """Entry id -> the ``jaxmdp.pad`` arguments of the stack of its size bucket (per setting)."""
    shapes = {}
    for setting in ("episodic", "continuous"):
        group = [e for e in entries if e["setting"] == setting]
        mdps = [build(e) for e in group]
        for bucket in jaxmdp.size_buckets(mdps, N_BUCKETS):
            stacked = jaxmdp.stack([mdps[i] for i in bucket])
            _, S, A, K = stacked.succ.shape
            for i in bucket:
                shapes[group[i]["id"]] = (S, A, K, stacked.H, stacked.max_starts)
    return shapes


@pytest.fixture(scope="module")
def built():
    cache = {}

    def get(entry):
        if entry["id"] not in cache:
            cache[entry["id"]] = build_reference_mdp(entry)
        return cache[entry["id"]]

    return get


@pytest.fixture(scope="module")
def padded_shapes(built):
    return _padded_shapes(reference_index(), built)


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


@pytest.mark.parametrize("entry", reference_params(every=False))
def test_reference_values_and_class(entry, built, padded_shapes):
    m = built(entry)
    values = jaxmdp.reference_values(jaxmdp.pad(m.strip(), *padded_shapes[entry["id"]]), "colosseum")
    for name in ("optimal", "worst", "random"):
        np.testing.assert_allclose(
            float(getattr(values, name)), entry[f"{name}_value"], rtol=1e-4, atol=1e-6, err_msg=name
        )
    assert jaxmdp.communication_class(m).name == entry["communication_class"]
