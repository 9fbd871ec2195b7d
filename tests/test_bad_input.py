"""Bad input gets a clear ValueError naming the parameter and what is allowed (issue 13, item 7; ``step`` is tested
in tests/test_env.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmdp
from jaxmdp import batching, episodic, registry, values
from jaxmdp.communication import CommunicationClass

CONTINUOUS = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=3)
EPISODIC = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=3)


def test_stack_refuses_an_empty_list():
    with pytest.raises(ValueError, match="at least one MDP"):
        jaxmdp.stack([])


def test_stack_refuses_batches():
    batch = jaxmdp.stack([CONTINUOUS, CONTINUOUS])
    with pytest.raises(ValueError, match="unbatched MDPs"):
        jaxmdp.stack([batch, batch])


def test_stack_refuses_mixed_dtypes():
    with jax.enable_x64(True):
        wide = CONTINUOUS.astype(jnp.float64)
        assert wide.dtype == jnp.float64
        with pytest.raises(ValueError, match=r"share a dtype; got \['float32', 'float64'\]"):
            jaxmdp.stack([CONTINUOUS, wide])


def test_pad_refuses_smaller_sizes_short_horizons_and_a_horizon_for_a_continuous_mdp():
    with pytest.raises(ValueError, match=r"cannot pad \(S, A, K\) = \(3, 2, \d\) down to \(2, 2, 3\)"):
        batching.pad(CONTINUOUS, 2, 2, 3)
    with pytest.raises(ValueError, match="H must be at least the MDP's horizon 3; got 1"):
        batching.pad(EPISODIC, 3, 2, 3, H=1)
    with pytest.raises(ValueError, match="H is for episodic MDPs only; got H=5"):
        batching.pad(CONTINUOUS, 3, 2, 3, H=5)


def test_unstack_refuses_an_unbatched_mdp():
    with pytest.raises(ValueError, match="unstack expects a batch with one leading axis"):
        jaxmdp.unstack(CONTINUOUS)


@pytest.mark.parametrize("perm", [[0, 1], [0, 0, 1], [0, 1, 3]])
def test_permute_states_refuses_non_permutations(perm):
    with pytest.raises(ValueError, match=r"perm must be a permutation of range\(3\)"):
        batching.permute_states(CONTINUOUS, perm)


def test_state_permutation_refuses_mdps_with_other_states():
    other = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)
    with pytest.raises(ValueError, match="same set of node labels"):
        batching.state_permutation(CONTINUOUS, other)


@pytest.mark.parametrize("name", ["", None, 3])
def test_register_refuses_an_empty_or_non_string_name(name):
    with pytest.raises(ValueError, match="name must be a non-empty string"):
        registry.register(name, lambda **kw: CONTINUOUS)


def test_communication_class_refuses_a_bad_shape():
    with pytest.raises(ValueError, match=r"T must be \[S, A, S\].*got T \(3, 2, 2\)"):
        jaxmdp.communication_class(CONTINUOUS.replace(T=CONTINUOUS.T[:, :, :2]))
    with pytest.raises(ValueError, match="expected an MDP or a batch with one leading axis"):
        jaxmdp.communication_class(CONTINUOUS.replace(T=CONTINUOUS.T[None, None]))


def test_communication_class_multichain():
    # Two absorbing states and a transient one that can reach either: two closed classes, so multichain (by hand).
    T = np.zeros((3, 2, 3))
    T[0, :, 0] = T[1, :, 1] = 1.0
    T[2, 0, 0] = T[2, 1, 1] = 1.0
    assert jaxmdp.communication_class(jaxmdp.custom_mdp(T, R=np.zeros((3, 2)))) == CommunicationClass.MULTICHAIN
    # One closed class (state 1 leads to 0): weakly communicating.
    T[1, :, 1], T[1, :, 0] = 0.0, 1.0
    assert jaxmdp.communication_class(jaxmdp.custom_mdp(T, R=np.zeros((3, 2)))) == (
        CommunicationClass.WEAKLY_COMMUNICATING)


def test_reference_values_refuses_an_unknown_variant():
    with pytest.raises(ValueError, match="variant must be 'paper' or 'colosseum'; got 'bogus'"):
        values.reference_values(CONTINUOUS, variant="bogus")


@pytest.mark.parametrize("helper", [episodic.reachable_pairs, episodic.time_augmented_kernel,
                                    episodic.episodic_graph_order, episodic.continuous_form])
def test_episodic_helpers_refuse_a_continuous_mdp(helper):
    with pytest.raises(ValueError, match="mdp must be episodic"):
        helper(CONTINUOUS)


def test_custom_mdp_reward_distribution_shapes():
    T = np.asarray(CONTINUOUS.T)
    with pytest.raises(ValueError, match=r"reward_mean must have shape \(3, 2, 3\); got \(3, 2\)"):
        jaxmdp.custom_mdp(T, reward_mean=np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"reward_conc must have shape \(3, 2, 3\); got \(3, 2\)"):
        jaxmdp.custom_mdp(T, reward_mean=np.zeros((3, 2, 3)), reward_conc=np.zeros((3, 2)))
