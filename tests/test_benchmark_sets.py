"""Named benchmark sets (benchmark.md §3) and the hyperparameter-search MDP samplers (benchmark.md §7)."""

import numpy as np
import pytest

import jaxmdp
from hardness.benchmark import samplers, sets
from jaxmdp.mdp_families import Beta, PointMass


@pytest.mark.parametrize("entry", [pytest.param(e, id=e.name) for e in sets.QUICK_TEST])
def test_quick_sets_build_with_the_reference_sizes_and_classes(entry):
    inst = next(i for i in sets.instances(entry.setting) if i.entry is entry)
    m = inst.build(0)
    assert m.n_states == entry.n_states
    assert m.H == entry.H
    assert jaxmdp.communication_class(m).name == entry.communication_class


def test_set_names_and_sizes():
    assert [len(sets.instances(n)) for n in sets.SETTINGS] == [20, 20, 20, 20]
    assert [len(sets.instances(n)) for n in sets.QUICK_SETS] == [7, 7]
    assert sets.canonical_name("continuous_quick-test") == "continuous quick test"
    assert sets.is_episodic("episodic-ergodic") and not sets.is_episodic("search continuous")
    with pytest.raises(ValueError, match="did you mean 'episodic ergodic'"):
        sets.instances("episodic ergodc")
    search = sets.instances("search continuous", n_per_family=2)
    assert len(search) == 14 and all(not i.episodic for i in search)
    assert len({i.name for i in search}) == 14


def test_instance_by_label_and_its_errors():
    every = sets.instances("continuous ergodic")
    assert [sets.instance("continuous_ergodic", inst.label) for inst in every] == every
    assert sets.instance("search continuous", "RiverSwim/sample_1", n_per_family=2) == sets.instances(
        "search continuous", n_per_family=2)[1]
    with pytest.raises(ValueError, match=r"label 'RiverSwim/prms_9' is not an MDP of the set 'continuous ergodic'; "
                                         r"did you mean 'RiverSwim/prms_\d'"):
        sets.instance("continuous ergodic", "RiverSwim/prms_9")
    with pytest.raises(ValueError, match="unknown benchmark set"):
        sets.instance("continuous ergodc", "RiverSwim/prms_0")


def test_same_seed_builds_the_same_instance_and_seeds_differ_where_the_family_does():
    fl = next(i for i in sets.instances("episodic quick test") if i.family == "FrozenLake")
    a, b, c = fl.build(3), fl.build(3), fl.build(4)
    assert np.array_equal(a.T, b.T)
    assert a.T.shape != c.T.shape or not np.array_equal(a.T, c.T)  # randomised actions and lake differ by seed


def test_river_swim_sampler_matches_a_hand_computed_random_state_sequence():
    rng = np.random.RandomState(42)
    d = rng.dirichlet([0.2, 0.2, 5])
    p_rand, p_lazy = 0.9 * d[0], 0.9 * d[1]
    size = int(min(2.5 + 200 / (45 * rng.random_sample() + 11), 25))  # episodic
    stochastic = [True, False][rng.randint(0, 2)]
    v = 2 * rng.random_sample() + 0.005
    first = samplers.sample_parameters("RiverSwim", 3, episodic=True, seed=42)[0]
    assert first["size"] == size
    assert first["p_rand"] == (None if p_rand < 0.01 else round(p_rand, 4))
    assert first["p_lazy"] == (None if p_lazy < 0.01 else round(p_lazy, 4))
    assert first["make_reward_stochastic"] is stochastic
    assert first["reward_variance_multiplier"] == round(v, 4)
    if stochastic:
        assert first["optimal_distribution"] == Beta(round(v, 4), round(v * (1 / 0.9 - 1), 4))
    else:
        assert first["sub_optimal_distribution"] == PointMass(0.005)
    # With seed 42 the first p_rand is below 0.01: the None rule applies to it.
    assert p_rand < 0.01 and first["p_rand"] is None


def test_minigrid_rooms_sampler_matches_a_hand_computed_random_state_sequence():
    rng = np.random.RandomState(7)
    d = rng.dirichlet([0.2, 0.2, 5])
    x, y, _ = rng.dirichlet([0.2, 0.2, 1])
    n_rooms = min(9, int(2 * x + 2) ** 2)
    room_size = min(9, int(7 * y + 3))  # continuous: no "- 3"
    n_start = rng.randint(1, 5)
    stochastic = [True, False][rng.randint(0, 2)]
    v = 2 * rng.random_sample() + 0.005
    first = samplers.sample_parameters("MiniGridRooms", 1, episodic=False, seed=7)[0]
    assert (first["n_rooms"], first["room_size"], first["n_starting_states"]) == (n_rooms, room_size, n_start)
    assert first["p_rand"] == (None if 0.9 * d[0] < 0.01 else round(0.9 * d[0], 4))
    assert first["p_lazy"] == (None if 0.9 * d[1] < 0.01 else round(0.9 * d[1], 4))
    size = int(room_size * np.sqrt(n_rooms))
    if stochastic:  # the reference's swapped parameters: the goal pays little
        assert first["optimal_distribution"] == Beta(round(v, 4), round(v * (size**2 - 1), 4))
        assert first["other_distribution"] == Beta(round(v * (size**2 - 1), 4), round(v, 4))
    else:
        assert first["optimal_distribution"] == PointMass(1.0)
    assert "size" not in first  # used by the distributions only


def test_every_sampler_rounds_to_four_decimals_and_builds():
    for episodic in (True, False):
        for family in samplers.FAMILIES:
            for params in samplers.sample_parameters(family, 4, episodic, seed=0):
                for k, x in params.items():
                    values = (x.a, x.b) if isinstance(x, Beta) else (x.value,) if isinstance(x, PointMass) else (x,)
                    for y in values:
                        if isinstance(y, float):
                            assert y == round(y, 4), (family, k, y)
                    if k in ("p_rand", "p_lazy"):
                        assert x is None or x >= 0.01
                assert "randomize_actions" not in params
            inst = samplers.sample_instances(episodic, 1, seed=0, families=[family])[0]
            assert inst.build(0).episodic == episodic


def test_sampler_errors():
    with pytest.raises(ValueError, match="family must be one of"):
        samplers.sample_parameters("MiniGridDoorKey", 1, True)
    with pytest.raises(ValueError, match="n must be a positive integer"):
        samplers.sample_parameters("Taxi", 0, True)
