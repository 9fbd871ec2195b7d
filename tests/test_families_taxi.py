"""Taxi (docs/families.md §2.7): walls, locations, worked example, dynamics, sizes, horizon, validation, rendering."""

import itertools

import numpy as np
import pytest

import jaxmdp
from jaxmdp.mdp_families import taxi as taxi_module
from jaxmdp.mdp_families.taxi import taxi_walls

LOCATIONS = [(0, 4), (0, 0), (4, 3), (3, 1)]  # size 5, defaults, seed 0 (spec's worked example)


def label(x, y, xp, yp, xd, yd):
    return f"X={x},Y={y},XPass={xp},YPass={yp},XDest={xd},YDest={yd}"


def row(m, lab, a):
    """``({next label: probability}, R)`` of the state labelled ``lab`` and action ``a``."""
    s = m.info.node_labels.index(lab)
    T = np.asarray(m.T[s, a], dtype=np.float64)
    return {m.info.node_labels[j]: round(float(T[j]), 6) for j in np.nonzero(T)[0]}, float(m.R[s, a])


@pytest.fixture(scope="module")
def example():
    return jaxmdp.make("Taxi", episodic=False, seed=0, size=5)


def as_strings(walls):
    return ["".join("1" if w else "0" for w in r) for r in walls]


def test_wall_patterns():
    assert as_strings(taxi_walls(5, 2, 1, 1)) == ["01010", "01010", "00000", "10101", "10101"]
    assert as_strings(taxi_walls(4, 1, 1, 1)) == ["0101", "0000", "1010", "0000"]
    assert (~taxi_walls(5, 1, 1, 1)).sum() == 18
    assert (~taxi_walls(6, 2, 1, 1)).sum() == 24
    assert (~taxi_walls(7, 2, 1, 1)).sum() == 32
    # width 2, space 2: units of two wall cells, two free cells between them, (2 + 2) // 2 free cells first on even
    # rows, the row cut at `size` cells
    assert as_strings(taxi_walls(7, 1, 2, 2)) == ["0011001", "0000000", "1100110", "0000000", "0011001",
                                                  "0000000", "1100110"]  # fmt: skip


def test_worked_example_locations_and_rows(example):
    m = example
    assert m.info.layout_value("locations") == tuple(LOCATIONS)
    on_board_at_dest = label(0, 4, -1, -1, 0, 4)
    nxt, r = row(m, on_board_at_dest, 5)  # DropOff at the destination: a new task, taxi stays
    expected = {label(0, 4, *p, *d): round(1 / 9, 6) for p in LOCATIONS[1:] for d in LOCATIONS if d != p}
    assert len(expected) == 9 and nxt == expected and r == 1.0
    assert row(m, on_board_at_dest, 4) == ({on_board_at_dest: 1.0}, 0.0)  # PickUp without a waiting passenger
    assert row(m, on_board_at_dest, 1) == ({on_board_at_dest: 1.0}, pytest.approx(0.1))  # MoveNorth: border
    waiting = label(0, 0, 0, 0, 4, 3)
    assert row(m, waiting, 4) == ({label(0, 0, -1, -1, 4, 3): 1.0}, pytest.approx(0.1))
    assert row(m, waiting, 5) == ({waiting: 1.0}, 0.0)  # DropOff without the passenger
    assert row(m, waiting, 0) == ({waiting: 1.0}, pytest.approx(0.1))  # MoveSouth: border
    assert row(m, waiting, 2) == ({label(1, 0, 0, 0, 4, 3): 1.0}, pytest.approx(0.1))  # MoveEast
    assert row(m, waiting, 1) == ({waiting: 1.0}, pytest.approx(0.1))  # MoveNorth: wall at (0, 1)


def test_moves_and_pickups_against_an_independent_model(example):
    m = example
    free = {(x, y) for x in range(5) for y in range(5) if as_strings(taxi_walls(5, 2, 1, 1))[x][y] == "0"}
    T = np.asarray(m.T, dtype=np.float64)
    index = {v: i for i, v in enumerate(m.info.node_values)}
    for s, (x, y, xp, yp, xd, yd) in enumerate(m.info.node_values):
        for a, (dx, dy) in enumerate([(0, -1), (0, 1), (1, 0), (-1, 0)]):
            target = (x + dx, y + dy) if (x + dx, y + dy) in free else (x, y)
            assert T[s, a, index[(*target, xp, yp, xd, yd)]] == 1.0
        picked = (x, y, -1, -1, xd, yd) if (xp, yp) == (x, y) else (x, y, xp, yp, xd, yd)
        assert T[s, 4, index[picked]] == 1.0


def test_random_action_outcomes_are_rewarded_with_the_chosen_action():
    m = jaxmdp.make("Taxi", episodic=False, seed=0, size=5, p_rand=0.1)
    at_dest = label(0, 4, -1, -1, 0, 4)
    # DropOff: its own outcomes (weight 0.9 + 0.1/6) deliver; the other actions' outcomes keep the passenger: failure
    assert row(m, at_dest, 5)[1] == pytest.approx(0.9 + 0.1 / 6, abs=1e-6)
    # PickUp: the random DropOff delivers, so the passenger is not on board afterwards: failure (0) everywhere
    assert row(m, at_dest, 4)[1] == 0.0
    assert row(m, at_dest, 2)[1] == pytest.approx(0.1, abs=1e-7)  # moves always pay the default


def test_starting_distribution(example):
    m = example
    P0 = np.asarray(m.P0)
    starts = [m.info.node_values[s] for s in np.nonzero(P0)[0]]
    expected = {
        (x, y, *p, *d)
        for p, d in itertools.permutations(LOCATIONS, 2)
        for x, y in zip(*np.nonzero(~taxi_walls(5, 2, 1, 1)))
    }
    assert len(starts) == 4 * 3 * 15 and set(starts) == expected
    np.testing.assert_allclose(P0[P0 > 0], 1 / 180, rtol=1e-6)


@pytest.mark.parametrize(
    "size, kw, S",
    [(5, {}, 240), (6, {}, 384), (7, {}, 512), (4, dict(length=1, n_locations=3), 108),
     (5, dict(length=1, n_locations=3), 162), (6, dict(length=1, n_locations=3), 243)],
)  # fmt: skip
def test_state_counts(size, kw, S):
    m = jaxmdp.make("Taxi", episodic=False, seed=1, size=size, **kw)
    n_loc = kw.get("n_locations", 4)
    free = int((~taxi_walls(size, kw.get("length", 2), 1, 1)).sum())
    assert S == free * n_loc**2 and (m.n_states, m.n_actions) == (S, 6)


@pytest.mark.parametrize("size, kw, H", [(4, dict(length=1, n_locations=3), 24), (5, {}, 37), (6, {}, 54)])
def test_fixed_formula_horizon(size, kw, H):
    m = jaxmdp.make("Taxi", episodic=True, seed=0, size=size, **kw)
    assert m.H == H == int(1.5 * size**2)


def test_requested_horizon_is_at_least_the_formula():
    kw = dict(episodic=True, seed=0, size=4, length=1, n_locations=3)
    assert jaxmdp.make("Taxi", H=40, **kw).H == 40
    assert jaxmdp.make("Taxi", H=3, **kw).H == 24


def test_two_locations_are_allowed_only_in_the_episodic_version():
    m = jaxmdp.make("Taxi", episodic=True, seed=0, size=4, length=1, n_locations=2)
    assert m.n_states == 12 * 4
    with pytest.raises(ValueError, match=r"n_locations must be an integer >= 3 for Taxi; got 2"):
        jaxmdp.make("Taxi", episodic=False, seed=0, size=4, length=1, n_locations=2)


def test_actions_are_never_randomized_and_parameters():
    kw = dict(episodic=False, seed=0, size=4, length=1, n_locations=3, p_rand=0.1)
    plain = jaxmdp.make("Taxi", randomize_actions=False, **kw)
    forced = jaxmdp.make("Taxi", randomize_actions=True, **kw)
    np.testing.assert_array_equal(plain.T, forced.T)
    assert forced.info.params == (
        ("seed", 0), ("randomize_actions", False), ("p_lazy", None), ("p_rand", 0.1),
        ("make_reward_stochastic", False), ("reward_variance_multiplier", 1.0),
        ("size", 4), ("length", 1), ("width", 1), ("space", 1), ("n_locations", 4),
        ("optimal_mean_reward", 0.9), ("sub_optimal_mean_reward", 0.2),
        ("default_r", "Deterministic(0.1)"), ("successfully_delivery_r", "Deterministic(1)"),
        ("failure_delivery_r", "Deterministic(0)"),
    )  # fmt: skip


def test_stochastic_defaults():
    m = jaxmdp.make("Taxi", episodic=False, seed=0, size=5, make_reward_stochastic=True, reward_variance_multiplier=2)
    assert m.info.param("default_r") == "Beta(2, 8)"
    assert m.info.param("successfully_delivery_r") == "Beta(2, 0.222222)"
    assert m.info.param("failure_delivery_r") == "Beta(2, 98)"
    nxt, r = row(m, label(0, 4, -1, -1, 0, 4), 5)
    assert r == pytest.approx(0.9, abs=1e-6)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(size=3), r"size must be an integer >= 4 for Taxi; got 3"),
        (dict(size=5, length=5), r"length must be an integer in \[0, 4\]"),
        (dict(size=5, width=0), r"width must be an integer in \[1, 4\]"),
        (dict(size=5, space=10), r"space must be an integer in \[0, 9\]"),
        (dict(size=4, n_locations=5), r"size > 2 sqrt\(n_locations\)"),
        (dict(size=5, sub_optimal_mean_reward=0.85), "optimal_mean_reward - 0.1 must exceed"),
        (
            dict(size=5, default_r=("deterministic", (0.0,)), successfully_delivery_r=("deterministic", (1.0,)),
                 failure_delivery_r=("deterministic", (0.0,))),
            "failure_delivery_r < default_r < successfully_delivery_r",
        ),  # fmt: skip
        (dict(size=5, default_r=("deterministic", (0.1,))), "all or none"),
        (dict(size=5, sub_optimal_mean_reward=0.0, make_reward_stochastic=True), r"^sub_optimal_mean_reward .*\(0, 1"),
        (dict(size=5, optimal_mean_reward=1.0, make_reward_stochastic=True), r"^optimal_mean_reward .*\(0, 1\)"),
        (dict(size=9, length=8, width=8), r"quadrant 1 of the 9x9 Taxi grid has no free cell"),
    ],
)
def test_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jaxmdp.make("Taxi", episodic=False, seed=0, **kwargs)


def test_rendering(example):
    m = example
    s = m.info.node_labels.index(label(0, 0, 0, 0, 4, 3))
    assert jaxmdp.render(m, s).split("\n") == ["X XDX", "X X X", "     ", " X X ", "AX X "]
    s = m.info.node_labels.index(label(2, 2, 3, 1, 0, 4))
    assert jaxmdp.render(m, s).split("\n") == ["X X X", "XPX X", "  A  ", " X X ", " X XD"]
    s = m.info.node_labels.index(label(4, 3, -1, -1, 0, 0))
    assert jaxmdp.render(m, s).split("\n") == ["X XAX", "X X X", "     ", " X X ", "DX X "]


def test_location_rejection_loop_is_bounded(monkeypatch):
    monkeypatch.setattr(taxi_module, "MAX_LOCATION_DRAWS", 1)
    with pytest.raises(ValueError, match="no set of Taxi locations pairwise farther apart than 2 was drawn in 1 tries"):
        jaxmdp.make("Taxi", episodic=False, seed=0, size=4, length=1, n_locations=3)
