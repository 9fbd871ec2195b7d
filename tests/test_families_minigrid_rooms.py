"""MiniGridRooms (docs/families.md §2.6): worked example, layout, draws, dynamics, sizes, horizons, validation,
rendering."""

import random

import numpy as np
import pytest

import jaxmdp
from jaxmdp.mdp_families.minigrid_rooms import admissible_cells, room_cells

DELTA = ((0, 1), (1, 0), (0, -1), (-1, 0))
NAMES = ("UP", "RIGHT", "DOWN", "LEFT")


def row(m, label, a):
    """``({next label: probability}, R)`` of the state labelled ``label`` and agent action ``a``."""
    s = m.info.node_labels.index(label)
    T = np.asarray(m.T[s, a], dtype=np.float64)
    return {m.info.node_labels[j]: round(float(T[j]), 6) for j in np.nonzero(T)[0]}, float(m.R[s, a])


@pytest.fixture(scope="module")
def example():
    """The spec's worked example: room size 3, 4 rooms, seed 0, no randomisation."""
    return jaxmdp.make("MiniGridRooms", episodic=False, seed=0, room_size=3, n_rooms=4, randomize_actions=False)


def test_worked_example(example):
    m = example
    assert m.info.layout_value("goal") == (1, 4)
    P0 = np.asarray(m.P0)
    assert {m.info.node_labels[s]: float(P0[s]) for s in np.nonzero(P0)[0]} == {
        "X=4,Y=4,Dir=RIGHT": 0.5,
        "X=6,Y=4,Dir=LEFT": 0.5,
    }
    assert row(m, "X=4,Y=4,Dir=RIGHT", 0) == ({"X=5,Y=4,Dir=RIGHT": 1.0}, 0.0)
    assert row(m, "X=4,Y=4,Dir=RIGHT", 1) == ({"X=4,Y=4,Dir=DOWN": 1.0}, 0.0)
    assert row(m, "X=4,Y=4,Dir=RIGHT", 2) == ({"X=4,Y=4,Dir=UP": 1.0}, 0.0)
    assert row(m, "X=4,Y=5,Dir=LEFT", 0) == ({"X=3,Y=5,Dir=LEFT": 1.0}, 0.0)  # through the door
    assert row(m, "X=4,Y=4,Dir=LEFT", 0) == ({"X=4,Y=4,Dir=LEFT": 1.0}, 0.0)  # wall
    assert row(m, "X=2,Y=4,Dir=LEFT", 0) == ({"X=1,Y=4,Dir=LEFT": 1.0}, 1.0)  # onto the goal


def test_layout_of_two_by_two_rooms():
    assert room_cells(3, (1, 0)) == [(4, 2), (5, 2), (6, 2), (4, 1), (5, 1), (6, 1), (4, 0), (5, 0), (6, 0)]
    cells = admissible_cells(3, 2)
    doors = {(3, 1), (3, 5), (1, 3), (5, 3)}
    rooms = {(x, y) for x in range(7) for y in range(7) if x != 3 and y != 3}
    assert cells == rooms | doors


def test_rooms_goal_and_starts_follow_the_documented_draw_order():
    for seed, rs, n_rooms, n in [(1, 2, 4, 3), (3, 3, 9, 5), (4, 2, 16, 1)]:
        k = int(np.sqrt(n_rooms))
        F, G = random.Random(seed), np.random.RandomState(seed)
        corners = [(0, 0), (0, k - 1), (k - 1, 0), (k - 1, k - 1)]
        start_room = corners.pop(F.randint(0, 3))
        goal_room = corners[F.randint(0, 2)]
        goal_cells = room_cells(rs, goal_room)
        G.shuffle(goal_cells)
        possible = [(x, y, d) for x, y in room_cells(rs, start_room) for d in range(4)]
        G.shuffle(possible)
        m = jaxmdp.make("MiniGridRooms", episodic=False, seed=seed, room_size=rs, n_rooms=n_rooms, n_starting_states=n)
        assert m.info.layout_value("goal") == goal_cells[0]
        P0 = np.asarray(m.P0)
        assert {m.info.node_labels[s] for s in np.nonzero(P0)[0]} == {
            f"X={x},Y={y},Dir={NAMES[d]}" for x, y, d in possible[:n]
        }
        np.testing.assert_allclose(P0[P0 > 0], 1.0 / n)


def test_every_transition_and_reward_against_the_rendered_walls():
    m = jaxmdp.make("MiniGridRooms", episodic=False, seed=2, room_size=2, n_rooms=9, randomize_actions=False)
    # Free cells read off the rendering (walls are "W"), an independent statement of the layout.
    grid = jaxmdp.render(m, 0).split("\n")[::-1]
    free = {(x, y) for y, line in enumerate(grid) for x, ch in enumerate(line) if ch != "W"}
    assert len(free) == 9 * 4 + 2 * 3 * 2
    goal = m.info.layout_value("goal")
    T, R = np.asarray(m.T, dtype=np.float64), np.asarray(m.R, dtype=np.float64)
    index = {v: i for i, v in enumerate(m.info.node_values)}
    for s, (x, y, d) in enumerate(m.info.node_values):
        fx, fy = x + DELTA[d][0], y + DELTA[d][1]
        forward = (fx, fy, d) if (fx, fy) in free else (x, y, d)
        for a, nxt in enumerate([forward, (x, y, (d + 1) % 4), (x, y, (d - 1) % 4)]):
            assert T[s, a, index[nxt]] == 1.0
            assert R[s, a] == (1.0 if nxt[:2] == goal else 0.0)


@pytest.mark.parametrize(
    "rs, n_rooms, S, H",
    [(2, 4, 80, 15), (3, 4, 160, 19), (4, 4, 272, 23), (3, 9, 372, 27), (5, 9, 948, 39), (3, 16, 672, 35)],
)
def test_state_counts_and_default_horizons(rs, n_rooms, S, H):
    m = jaxmdp.make("MiniGridRooms", episodic=True, seed=rs + n_rooms, room_size=rs, n_rooms=n_rooms)
    k = int(np.sqrt(n_rooms))
    assert S == 4 * (n_rooms * rs**2 + 2 * k * (k - 1)) and H == 2 * k * (rs + 1) + 3
    assert (m.n_states, m.n_actions, m.H) == (S, 3, H)


def test_default_distributions_and_parameter_order():
    m = jaxmdp.make("MiniGridRooms", episodic=True, seed=0, room_size=2)
    assert m.info.params[6:] == (
        ("room_size", 2), ("n_rooms", 4), ("n_starting_states", 2),
        ("optimal_distribution", "Deterministic(1)"), ("other_distribution", "Deterministic(0)"), ("H", 15),
    )  # fmt: skip
    s = jaxmdp.make("MiniGridRooms", episodic=False, seed=0, room_size=3, n_rooms=9, make_reward_stochastic=True)
    assert s.info.param("optimal_distribution") == "Beta(80, 1)"  # size = 3 * sqrt(9) = 9
    assert s.info.param("other_distribution") == "Beta(1, 80)"


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(room_size=1), r"room_size must be an integer >= 2 for MiniGridRooms; got 1"),
        (dict(room_size=3, n_rooms=5), r"n_rooms must be a perfect square >= 4 .*got 5"),
        (dict(room_size=3, n_rooms=1), r"n_rooms must be a perfect square >= 4 .*got 1"),
        (dict(room_size=3, n_rooms=8), r"n_rooms must be a perfect square"),
        (dict(room_size=3, n_rooms=4.0), r"n_rooms must be a perfect square"),
        (dict(room_size=3, n_starting_states=0), r"n_starting_states must be an integer in \[1, 36\]"),
        (dict(room_size=3, n_starting_states=37), r"n_starting_states must be an integer in \[1, 36\] .*got 37"),
        (dict(room_size=3, other_distribution=("deterministic", (0.0,))), "all or none"),
    ],
)
def test_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jaxmdp.make("MiniGridRooms", episodic=False, seed=0, **kwargs)


def test_all_start_room_nodes_may_start():
    m = jaxmdp.make("MiniGridRooms", episodic=False, seed=0, room_size=2, n_starting_states=16)
    np.testing.assert_allclose(np.sort(np.asarray(m.P0))[-16:], 1 / 16)


def test_rendering(example):
    m = example
    s = m.info.node_labels.index("X=4,Y=4,Dir=RIGHT")
    assert jaxmdp.render(m, s).split("\n") == [
        "   W   ",
        "       ",
        " G W>  ",
        "W WWW W",
        "   W   ",
        "       ",
        "   W   ",
    ]
    s = m.info.node_labels.index("X=3,Y=1,Dir=DOWN")  # standing in a door
    assert jaxmdp.render(m, s).split("\n")[5] == "   v   "
