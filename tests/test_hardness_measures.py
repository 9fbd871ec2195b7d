"""measures(), normalize(), and batching: vmap over a stacked batch equals one-at-a-time and padding changes nothing.

The batch mixes sizes, action counts and (episodic) horizons, so every member is padded in states, actions,
successor slots and time.
"""

import jax
import numpy as np
import pytest

import hardness
import jaxmdp
from jaxmdp import episodic

from conftest import random_mdp

# The colosseum procedures do the same float operations row by row whatever the padding. The paper variant's exact
# discounted values come from a dense linear solve (solve_discounted), whose LU round-off depends on the matrix size;
# float32 values ~ 10 then move by ~1e-6 and the gap sum, which divides by gaps ~ 0.1, by ~1e-5 relative.
RTOL = {"paper": 3e-5, "colosseum": 2e-6}


def all_values(m, variant, cf=None):
    r = hardness.measures(m, variant=variant, continuous_form=cf)
    return np.array([r.diameter.value, r.value_norm.value, r.sum_reciprocal_gaps.value])


@pytest.fixture(scope="module")
def continuous_members():
    rng = np.random.default_rng(31)
    return [
        random_mdp(rng, S=4, A=2),
        random_mdp(rng, S=6, A=3),
        jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, p_lazy=0.1, p_rand=0.2, randomize_actions=False),
    ]


@pytest.fixture(scope="module")
def episodic_members():
    rng = np.random.default_rng(32)
    return [
        random_mdp(rng, S=4, A=2, H=3, sparsity=0.3),
        random_mdp(rng, S=5, A=3, H=5, sparsity=0.3),
        jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4, p_lazy=0.1, randomize_actions=False),
    ]


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_vmap_over_stack_equals_single_continuous(continuous_members, variant):
    single = np.stack([all_values(m, variant) for m in continuous_members])
    batch = jaxmdp.stack(continuous_members)
    out = jax.jit(jax.vmap(lambda m: hardness.measures(m, variant=variant)))(batch)
    got = np.stack([out.diameter.value, out.value_norm.value, out.sum_reciprocal_gaps.value], axis=1)
    np.testing.assert_allclose(got, single, rtol=RTOL[variant])
    assert np.all(out.diameter.converged) and np.all(out.value_norm.finite)


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_vmap_over_stack_equals_single_episodic(episodic_members, variant):
    forms = [episodic.continuous_form(m) for m in episodic_members]
    single = np.stack([all_values(m, variant, cf) for m, cf in zip(episodic_members, forms)])
    batch = jaxmdp.stack(episodic_members)
    cfs = episodic.stack_continuous_forms(forms)
    fn = jax.jit(jax.vmap(lambda m, cf: hardness.measures(m, variant=variant, continuous_form=cf)))
    out = fn(batch, cfs)
    got = np.stack([out.diameter.value, out.value_norm.value, out.sum_reciprocal_gaps.value], axis=1)
    np.testing.assert_allclose(got, single, rtol=RTOL[variant])


def test_padding_one_mdp_changes_nothing(continuous_members):
    m = continuous_members[0]
    padded = jaxmdp.pad(m.strip(), 9, 4, m.max_successors + 2)
    for variant in ("paper", "colosseum"):
        np.testing.assert_allclose(all_values(padded, variant), all_values(m, variant), rtol=RTOL[variant])


def test_measures_match_individual_calls(continuous_members):
    m = continuous_members[2]
    r = hardness.measures(m, 0.95)
    assert float(r.diameter.value) == float(hardness.diameter(m).value)
    assert float(r.value_norm.value) == float(hardness.value_norm(m, 0.95).value)
    assert float(r.sum_reciprocal_gaps.value) == float(hardness.sum_reciprocal_gaps(m, 0.95).value)


def test_normalize_hand_worked():
    x = np.array([2.0, 4.0, 3.0, 6.0])
    np.testing.assert_allclose(hardness.normalize(x), [0.0, 0.5, 0.25, 1.0])
    np.testing.assert_allclose(hardness.normalize(np.array([1.0, 1.00005, 1.0])), [0.5, 0.5, 0.5])
    grid = np.array([[0.0, 1.0, 2.0], [5.0, 5.0, 5.0]])
    np.testing.assert_allclose(hardness.normalize(grid, axis=1), [[0.0, 0.5, 1.0], [0.5, 0.5, 0.5]])
    np.testing.assert_allclose(hardness.normalize(grid, axis=0), [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    out = np.asarray(hardness.normalize(np.array([1.0, np.inf, 3.0])))
    np.testing.assert_allclose(out[[0, 2]], [0.0, 1.0])
    assert np.isnan(out[1])


@pytest.mark.parametrize("variant, batch_size", [("paper", 2), ("colosseum", 1)])
def test_measures_many_equals_single_calls_in_input_order(continuous_members, episodic_members, variant, batch_size):
    # Episodic and continuous members interleaved; two buckets per setting, so members are regrouped and reordered.
    # Members one at a time (lax.map) and two at a time (vmapped within the map); each batch size is a compilation
    # per bucket, so each variant takes one of them.
    mdps = [episodic_members[2], continuous_members[1], episodic_members[0], continuous_members[2],
            continuous_members[0], episodic_members[1]]
    single = np.stack(
        [all_values(m, variant, episodic.continuous_form(m) if m.episodic and variant == "colosseum" else None)
         for m in mdps]
    )
    out = hardness.measures_many(mdps, variant=variant, n_buckets=2, batch_size=batch_size)
    got = np.stack([out.diameter.value, out.value_norm.value, out.sum_reciprocal_gaps.value], axis=1)
    np.testing.assert_allclose(got, single, rtol=RTOL[variant])
    assert out.diameter.converged.shape == (6,) and np.all(out.diameter.converged)


def test_measures_many_rejects_bad_input(continuous_members):
    with pytest.raises(ValueError, match="at least one"):
        hardness.measures_many([])
    with pytest.raises(ValueError, match="batch_size"):
        hardness.measures_many(continuous_members, batch_size=0)
    with pytest.raises(ValueError, match="not stacked"):
        hardness.measures_many([jaxmdp.stack(continuous_members)])
