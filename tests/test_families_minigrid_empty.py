"""MiniGridEmpty (docs/families.md §2.5): worked example, draws, dynamics, sizes, horizons, validation, rendering."""

import numpy as np
import pytest

import jaxmdp
from jaxmdp.mdp_families.minigrid_empty import side_cells

DIRS = {"UP": (0, 1), "RIGHT": (1, 0), "DOWN": (0, -1), "LEFT": (-1, 0)}
NAMES = ("UP", "RIGHT", "DOWN", "LEFT")


def row(m, label, a):
    """``({next label: probability}, R)`` of the state labelled ``label`` and agent action ``a``."""
    s = m.info.node_labels.index(label)
    T = np.asarray(m.T[s, a], dtype=np.float64)
    return {m.info.node_labels[j]: round(float(T[j]), 6) for j in np.nonzero(T)[0]}, float(m.R[s, a])


@pytest.fixture(scope="module")
def example():
    """The spec's worked example: size 4, seed 0, two starts, no randomisation."""
    return jaxmdp.make(
        "MiniGridEmpty", episodic=False, seed=0, size=4, n_starting_states=2, randomize_actions=False
    )


def test_worked_example_starts_goal_and_rows(example):
    m = example
    assert m.info.layout_value("goal") == (3, 0)
    P0 = np.asarray(m.P0)
    starts = {m.info.node_labels[s]: float(P0[s]) for s in np.nonzero(P0)[0]}
    assert starts == {"X=0,Y=2,Dir=LEFT": 0.5, "X=0,Y=3,Dir=LEFT": 0.5}
    assert m.info.node_labels[0] == "X=0,Y=2,Dir=LEFT"  # the first start is the first discovered node
    assert row(m, "X=0,Y=2,Dir=LEFT", 0) == ({"X=0,Y=2,Dir=LEFT": 1.0}, 0.0)  # bumps into the wall
    assert row(m, "X=0,Y=2,Dir=LEFT", 1) == ({"X=0,Y=2,Dir=UP": 1.0}, 0.0)
    assert row(m, "X=0,Y=2,Dir=LEFT", 2) == ({"X=0,Y=2,Dir=DOWN": 1.0}, 0.0)
    # entering the goal and turning on it pay the optimal reward
    assert row(m, "X=2,Y=0,Dir=RIGHT", 0) == ({"X=3,Y=0,Dir=RIGHT": 1.0}, 1.0)
    assert row(m, "X=3,Y=0,Dir=UP", 1) == ({"X=3,Y=0,Dir=RIGHT": 1.0}, 1.0)
    assert row(m, "X=3,Y=0,Dir=UP", 0) == ({"X=3,Y=1,Dir=UP": 1.0}, 0.0)


def test_start_and_goal_follow_the_documented_draw_order():
    # Replay the spec's G draws for several seeds and sizes: side, goal index, shuffle, one direction per start.
    for seed, size, n in [(1, 5, 3), (2, 6, 1), (5, 3, 3), (7, 4, 4)]:
        G = np.random.RandomState(seed)
        side = G.randint(4)
        goal = side_cells(size, (side + 2) % 4)[G.randint(size)]
        cells = side_cells(size, side)
        G.shuffle(cells)
        expected = {f"X={x},Y={y},Dir={NAMES[G.randint(4)]}" for x, y in cells[:n]}
        m = jaxmdp.make("MiniGridEmpty", episodic=False, seed=seed, size=size, n_starting_states=n)
        assert m.info.layout_value("goal") == goal
        P0 = np.asarray(m.P0)
        assert {m.info.node_labels[s] for s in np.nonzero(P0)[0]} == expected
        np.testing.assert_allclose(P0[P0 > 0], 1.0 / n)


def test_sides_listing_order():
    assert side_cells(3, 0) == [(0, 0), (0, 1), (0, 2)]
    assert side_cells(3, 1) == [(0, 0), (1, 0), (2, 0)]
    assert side_cells(3, 2) == [(2, 2), (2, 1), (2, 0)]
    assert side_cells(3, 3) == [(2, 2), (1, 2), (0, 2)]


def test_every_transition_and_reward_against_an_independent_model():
    size = 5
    m = jaxmdp.make("MiniGridEmpty", episodic=False, seed=3, size=size, randomize_actions=False)
    goal = m.info.layout_value("goal")
    T, R = np.asarray(m.T, dtype=np.float64), np.asarray(m.R, dtype=np.float64)
    index = {v: i for i, v in enumerate(m.info.node_values)}
    for s, (x, y, d) in enumerate(m.info.node_values):
        dx, dy = DIRS[NAMES[d]]
        forward = (min(max(x + dx, 0), size - 1), min(max(y + dy, 0), size - 1), d)
        for a, nxt in enumerate([forward, (x, y, (d + 1) % 4), (x, y, (d - 1) % 4)]):
            assert T[s, a, index[nxt]] == 1.0
            assert R[s, a] == (1.0 if nxt[:2] == goal else 0.0)


def test_lazy_and_random_action_rows():
    m = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=4, p_lazy=0.1, p_rand=0.2, randomize_actions=False)
    # own 0.9 * (0.8 + 0.2/3) = 0.78, lazy 0.1, each other action 0.9 * 0.2 / 3 = 0.06
    nxt, _ = row(m, "X=0,Y=2,Dir=LEFT", 1)
    assert nxt == {"X=0,Y=2,Dir=UP": 0.78, "X=0,Y=2,Dir=LEFT": 0.16, "X=0,Y=2,Dir=DOWN": 0.06}
    nxt, r = row(m, "X=2,Y=0,Dir=RIGHT", 1)  # TurnRight next to the goal: the p_rand forward move pays 1
    assert nxt == {"X=2,Y=0,Dir=DOWN": 0.78, "X=2,Y=0,Dir=RIGHT": 0.1, "X=3,Y=0,Dir=RIGHT": 0.06, "X=2,Y=0,Dir=UP": 0.06}
    assert r == pytest.approx(0.06, abs=1e-7)


def test_randomized_actions_permute_each_row_set():
    kw = dict(episodic=False, seed=4, size=4, p_rand=0.3)
    plain = jaxmdp.make("MiniGridEmpty", randomize_actions=False, **kw)
    perm = jaxmdp.make("MiniGridEmpty", randomize_actions=True, **kw)
    assert perm.info.node_labels == plain.info.node_labels
    Tp, Tr = np.asarray(plain.T), np.asarray(perm.T)
    Rp, Rr = np.asarray(plain.R), np.asarray(perm.R)
    moved = 0
    for s in range(plain.n_states):
        order_p = sorted(range(3), key=lambda a: tuple(Tp[s, a]))
        order_r = sorted(range(3), key=lambda a: tuple(Tr[s, a]))
        np.testing.assert_array_equal(Tp[s, order_p], Tr[s, order_r])
        np.testing.assert_array_equal(Rp[s, order_p], Rr[s, order_r])
        moved += not np.array_equal(Tp[s], Tr[s])
    assert moved > plain.n_states // 2


@pytest.mark.parametrize(
    "size, S, H", [(3, 36, 9), (4, 64, 11), (6, 144, 15), (8, 256, 19), (10, 400, 23), (12, 576, 27), (14, 784, 31)]
)
def test_state_counts_and_default_horizons(size, S, H):
    m = jaxmdp.make("MiniGridEmpty", episodic=True, seed=size, size=size)
    assert (m.n_states, m.n_actions, m.H) == (S, 3, H)


def test_requested_horizon():
    assert jaxmdp.make("MiniGridEmpty", episodic=True, seed=0, size=4, H=30).H == 30
    assert jaxmdp.make("MiniGridEmpty", episodic=True, seed=0, size=4, H=5).H == 11  # never below H_min


def test_default_distributions_and_parameter_order():
    m = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=4)
    assert m.info.params == (
        ("seed", 0), ("randomize_actions", True), ("p_lazy", None), ("p_rand", None),
        ("make_reward_stochastic", False), ("reward_variance_multiplier", 1.0),
        ("size", 4), ("n_starting_states", 1),
        ("optimal_distribution", "Deterministic(1)"), ("other_distribution", "Deterministic(0)"),
    )  # fmt: skip
    s = jaxmdp.make(
        "MiniGridEmpty", episodic=False, seed=0, size=4, make_reward_stochastic=True, reward_variance_multiplier=2.0
    )
    assert s.info.param("optimal_distribution") == "Beta(30, 2)"
    assert s.info.param("other_distribution") == "Beta(2, 30)"
    goal = s.info.layout_value("goal")
    mean, conc = np.asarray(s.reward_mean), np.asarray(s.reward_conc)
    for j, v in enumerate(s.info.node_values):
        expected = 30 / 32 if v[:2] == goal else 2 / 32
        np.testing.assert_allclose(mean[:, :, j][np.asarray(s.T)[:, :, j] > 0], expected, rtol=1e-6)
    np.testing.assert_array_equal(conc[np.asarray(s.T) > 0], 32.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(size=2), r"size must be an integer >= 3 for MiniGridEmpty; got 2"),
        (dict(size=4.0), r"size must be an integer >= 3"),
        (dict(size=4, n_starting_states=0), r"n_starting_states must be an integer in \[1, 4\]"),
        (dict(size=4, n_starting_states=5), r"n_starting_states must be an integer in \[1, 4\] .*got 5"),
        (dict(size=4, optimal_distribution=("deterministic", (1.0,))), "all or none"),
        (
            dict(size=4, optimal_distribution=("beta", (1, 2)), other_distribution=("beta", (2, 1))),
            "stochastic but make_reward_stochastic=False",
        ),
        (dict(size=4, p_lazy=1.0), "p_lazy must lie in"),
        (dict(size=4, reward_variance_multiplier=0.0), "reward_variance_multiplier must be > 0"),
    ],
)
def test_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, **kwargs)


def test_explicit_distributions():
    m = jaxmdp.make(
        "MiniGridEmpty", episodic=False, seed=0, size=4, make_reward_stochastic=True, randomize_actions=False,
        optimal_distribution=("beta", (9, 1)), other_distribution=jaxmdp.Beta(1, 9),
    )  # fmt: skip
    assert row(m, "X=2,Y=0,Dir=RIGHT", 0)[1] == pytest.approx(0.9)
    assert row(m, "X=0,Y=2,Dir=LEFT", 0)[1] == pytest.approx(0.1)


def test_rendering_shows_the_asked_node(example):
    m = example
    labels = m.info.node_labels
    assert jaxmdp.render(m, labels.index("X=0,Y=2,Dir=LEFT")) == "    \n<   \n    \n   G"
    assert jaxmdp.render(m, labels.index("X=1,Y=3,Dir=RIGHT")) == " >  \n    \n    \n   G"
    assert jaxmdp.render(m, labels.index("X=3,Y=0,Dir=DOWN")) == "    \n    \n    \n   v"  # the arrow hides G
    assert jaxmdp.render(m, labels.index("X=2,Y=1,Dir=UP"), h=7) == "H=7 \n____\n    \n    \n  ^ \n   G"
