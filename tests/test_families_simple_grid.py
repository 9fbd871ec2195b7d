"""SimpleGrid (docs/families.md §2.3): starts, corner-loop rewards, horizon, validation and rendering."""

import inspect
import random

import numpy as np
import pytest

import jaxmdp
from jaxmdp.mdp_families.simple_grid import SimpleGridFamily, SimpleGridReward, simple_grid

UP, RIGHT, DOWN, LEFT, NO_OP = range(5)


def _make(episodic=False, **kw):
    kw.setdefault("randomize_actions", False)
    return jaxmdp.make("SimpleGrid", episodic=episodic, seed=kw.pop("seed", 0), **kw)


def _idx(m, x, y):
    return m.info.node_labels.index(f"X={x},Y={y}")


def _family(size, **kw):
    """The family object with the builder's defaults (the builder's declaration is where they live)."""
    own = inspect.signature(SimpleGridFamily).parameters
    defaults = {name: p.default for name, p in inspect.signature(simple_grid).parameters.items()
                if p.default is not p.empty}
    rewards = SimpleGridFamily.reward_parameters.arguments(defaults, stochastic=False, variance_multiplier=1.0)
    given = {name: value for name, value in defaults.items() if name in own}
    return SimpleGridFamily(**{**given, "size": size, "rewards": rewards, **kw})


def test_worked_example_starts_size_4_seed_0():
    fam = _family(4, n_starting_states=3)
    starts, probs, possible = fam.starting_nodes(np.random.RandomState(0), random.Random(0))
    assert [tuple(n) for n in possible] == [(2, 1), (2, 2), (1, 2), (1, 1), (0, 1), (0, 2), (1, 0), (1, 3), (2, 0)]
    assert [tuple(n) for n in starts] == [(2, 1), (1, 2), (2, 2)]
    assert probs == [1 / 3] * 3
    m = _make(size=4, n_starting_states=3, p_lazy=0.1)
    P0 = np.asarray(m.P0)
    assert m.info.node_labels[0] == "X=2,Y=1"  # the first starting node is expanded first
    for x, y in [(2, 1), (1, 2), (2, 2)]:
        assert P0[_idx(m, x, y)] == pytest.approx(1 / 3)
    assert P0.sum() == pytest.approx(1.0)


def test_closest_tie_group_is_shuffled_with_the_instance_generator():
    # Odd size: one centre cell, then the 4 cells at distance 1 in row-major order, then the 4 diagonal ones.
    fam = _family(5, n_starting_states=1)
    _, _, possible = fam.starting_nodes(np.random.RandomState(0), random.Random(0))
    assert [tuple(n) for n in possible[:9]] == [(2, 2), (1, 2), (2, 1), (2, 3), (3, 2), (1, 1), (1, 3), (3, 1), (3, 3)]
    assert len(possible) == 16
    # Even size: the 4 central cells are the shuffled group; G.shuffle of a 4-list draws 3 bounded integers.
    orders = set()
    for seed in range(8):
        _, _, possible = _family(6).starting_nodes(np.random.RandomState(seed), random.Random(seed))
        head = [tuple(n) for n in possible[:4]]
        assert sorted(head) == [(2, 2), (2, 3), (3, 2), (3, 3)]
        expected = [[2, 2], [2, 3], [3, 2], [3, 3]]
        np.random.RandomState(seed).shuffle(expected)
        assert head == [tuple(c) for c in expected]
        orders.add(tuple(head))
    assert len(orders) > 1


def test_worked_example_rows_with_p_lazy():
    m = _make(size=4, n_starting_states=3, p_lazy=0.1)
    T, R = np.asarray(m.T), np.asarray(m.R)
    s00, s01, s30, s31 = _idx(m, 0, 0), _idx(m, 0, 1), _idx(m, 3, 0), _idx(m, 3, 1)
    np.testing.assert_allclose(T[s00, UP, [s01, s00]], [0.9, 0.1], atol=1e-7)
    assert R[s00, UP] == pytest.approx(0.45)  # 0.9 * 0.5 (other) + 0.1 * 0 (bad corner loop under XOR)
    for a in (DOWN, LEFT, NO_OP):
        assert T[s00, a, s00] == pytest.approx(1.0) and R[s00, a] == 0.0
    for a in (RIGHT, DOWN, NO_OP):  # (3, 0) is a good corner under XOR
        assert T[s30, a, s30] == pytest.approx(1.0) and R[s30, a] == pytest.approx(1.0)
    np.testing.assert_allclose(T[s30, UP, [s31, s30]], [0.9, 0.1], atol=1e-7)
    assert R[s30, UP] == pytest.approx(0.55)
    # A lazy self-loop away from the corners pays the "other" reward: R = 0.5 everywhere in the interior.
    assert np.allclose(R[_idx(m, 1, 1)], 0.5)


@pytest.mark.parametrize(
    "reward_type,good",
    [
        ("AND", {(3, 3)}),
        ("NAND", {(0, 0), (0, 3), (3, 0)}),
        ("OR", {(0, 3), (3, 0), (3, 3)}),
        ("XOR", {(0, 3), (3, 0)}),
    ],
)
def test_reward_types_choose_the_good_corners(reward_type, good):
    for rt in (reward_type, int(SimpleGridReward[reward_type]), SimpleGridReward[reward_type]):
        m = _make(size=4, reward_type=rt)
        R = np.asarray(m.R)
        for x in (0, 3):
            for y in (0, 3):
                assert R[_idx(m, x, y), NO_OP] == (1.0 if (x, y) in good else 0.0)
        assert dict(m.info.params)["reward_type"] == reward_type


def test_state_count_and_full_parameter_order():
    m = _make(size=5, seed=1, p_rand=0.1, n_starting_states=2)
    assert m.n_states == 25 and m.n_actions == 5
    assert m.info.params == (
        ("seed", 1),
        ("randomize_actions", False),
        ("p_lazy", None),
        ("p_rand", 0.1),
        ("make_reward_stochastic", False),
        ("reward_variance_multiplier", 1.0),
        ("size", 5),
        ("reward_type", "XOR"),
        ("n_starting_states", 2),
        ("optimal_mean_reward", 0.9),
        ("sub_optimal_mean_reward", 0.2),
        ("optimal_distribution", "Deterministic(1)"),
        ("sub_optimal_distribution", "Deterministic(0)"),
        ("other_distribution", "Deterministic(0.5)"),
    )


@pytest.mark.parametrize("v", [1.0, 0.5])
def test_stochastic_default_distributions(v):
    m = _make(size=4, make_reward_stochastic=True, reward_variance_multiplier=v)
    mean, conc = np.asarray(m.reward_mean), np.asarray(m.reward_conc)
    s30, s00, s11, s12 = _idx(m, 3, 0), _idx(m, 0, 0), _idx(m, 1, 1), _idx(m, 1, 2)
    # optimal Beta(v, v/9) (mean 0.9), sub-optimal Beta(v, 49 v) (mean 0.02), other Beta(v, 4 v) (mean 0.2).
    for (s, a, t), (alpha, beta) in {
        (s30, NO_OP, s30): (v, v * (1 / 0.9 - 1)),
        (s00, NO_OP, s00): (v, 49 * v),
        (s11, UP, s12): (v, 4 * v),
        (s11, NO_OP, s11): (v, 4 * v),  # an interior self-loop is not a corner loop
    }.items():
        assert conc[s, a, t] == pytest.approx(alpha + beta, rel=1e-6)
        assert mean[s, a, t] == pytest.approx(alpha / (alpha + beta), rel=1e-6)


@pytest.mark.parametrize("size,H", [(3, 4), (4, 6), (5, 8), (6, 10), (8, 13), (10, 17), (13, 22)])
def test_default_horizon_table(size, H):
    assert _make(episodic=True, size=size).H == H
    assert _make(episodic=True, size=size, H=H + 5).H == H + 5
    assert _make(episodic=True, size=size, H=1).H == H  # the requested horizon is raised to the minimum


def test_default_horizon_table_large_sizes():
    assert [_make(episodic=True, size=size).H for size in (16, 20)] == [28, 36]


def test_default_horizon_is_seed_independent():
    assert {_make(episodic=True, size=6, seed=s, n_starting_states=2).H for s in range(4)} == {10}


def test_validation_errors():
    with pytest.raises(ValueError, match="size must be an integer >= 2"):
        _make(size=1)
    with pytest.raises(ValueError, match=r"n_starting_states must be an integer in \[1, 9\] for SimpleGrid"):
        _make(size=4, n_starting_states=10)
    with pytest.raises(ValueError, match="n_starting_states"):
        _make(size=4, n_starting_states=0)
    with pytest.raises(ValueError, match="reward_type must be 0-3"):
        _make(size=4, reward_type=4)
    with pytest.raises(ValueError, match="reward_type must be 0-3"):
        _make(size=4, reward_type="MAYBE")
    with pytest.raises(ValueError, match="optimal_mean_reward - 0.1 must exceed sub_optimal_mean_reward"):
        _make(size=4, optimal_mean_reward=0.3, sub_optimal_mean_reward=0.2)
    with pytest.raises(ValueError, match=r"optimal_mean_reward must lie in \(0, 1\)"):
        _make(size=4, make_reward_stochastic=True, optimal_mean_reward=1.2)
    with pytest.raises(ValueError, match=r"sub_optimal_mean_reward must lie in \(0, 1\)"):
        _make(size=4, make_reward_stochastic=True, sub_optimal_mean_reward=0.0)
    with pytest.raises(ValueError, match="all or none"):
        _make(size=4, other_distribution=("deterministic", (0.1,)))
    with pytest.raises(ValueError, match="p_lazy must lie in"):
        _make(size=4, p_lazy=-0.1)


@pytest.mark.parametrize(
    "reward_type,corners",
    [("XOR", ("+", "-", "-", "+")), ("AND", ("-", "+", "-", "-")), ("NAND", ("+", "-", "+", "+")),
     ("OR", ("+", "+", "-", "+"))],
)
def test_rendering_marks_corners_and_agent(reward_type, corners):
    # corners = symbols at (0, top), (top, top), (0, 0), (top, 0) i.e. printed top-left, top-right, bottom-left,
    # bottom-right.
    m = _make(size=3, reward_type=reward_type)
    tl, tr, bl, br = corners
    assert jaxmdp.render(m, _idx(m, 1, 1)).split("\n") == [f"{tl} {tr}", " A ", f"{bl} {br}"]
    assert jaxmdp.render(m, _idx(m, 2, 0)).split("\n")[-1] == f"{bl} A"
    assert jaxmdp.render(m, _idx(m, 1, 2)).split("\n")[0] == f"{tl}A{tr}"


def test_episodic_rendering_header():
    m = _make(episodic=True, size=4)
    assert jaxmdp.render(m, _idx(m, 0, 0), h=3).split("\n") == ["H=3 ", "____", "+  -", "    ", "    ", "A  +"]
