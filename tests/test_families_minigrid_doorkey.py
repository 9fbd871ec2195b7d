"""MiniGridDoorKey (new family, paper App. C): layout draws, dynamics, structure, optimal return, rendering."""

from collections import deque

import jax
import numpy as np
import pytest

import jaxmdp
from jaxmdp import dynamic_programming as dp

F, TR, TL, PICK, OPEN = range(5)  # base actions

# seed 0, size 5 (rows printed top to bottom, Y = 4 .. 0):
#   "  W  "
#   "G W  "      goal (0, 3)
#   "  W K"      key (4, 2)
#   "  W^ "      start (3, 1) facing UP
#   "  C  "      door (2, 0) in the vertical wall X = 2
START = "X=3,Y=1,Dir=UP,HasKey=0,DoorOpen=0"
# Hand count of the shortest way to the goal: step up and turn to face the key, pick it up (3 actions); turn down,
# walk to (3, 0), turn left to face the door, open it (5); walk through the door to (0, 0) (3); turn up and walk to the
# goal (0, 3) (4). Fifteen actions; the last one enters the goal.
HAND_PLAN = [F, TR, PICK, TR, F, F, TR, OPEN, F, F, F, TR, F, F, F]


def row(m, label, a):
    s = m.info.node_labels.index(label)
    T = np.asarray(m.T[s, a], dtype=np.float64)
    return {m.info.node_labels[j]: round(float(T[j]), 6) for j in np.nonzero(T)[0]}, float(m.R[s, a])


@pytest.fixture(scope="module")
def episodic():
    return jaxmdp.make(
        "MiniGridDoorKey", episodic=True, seed=0, size=5, n_starting_states=1, randomize_actions=False
    )


@pytest.fixture(scope="module")
def continuous():
    return jaxmdp.make("MiniGridDoorKey", episodic=False, seed=0, size=5, randomize_actions=False)


def test_layout_follows_the_documented_draws(episodic):
    for seed, size in [(0, 5), (1, 5), (3, 6), (8, 4)]:
        G = np.random.RandomState(seed)
        vertical = G.randint(2) == 0
        w = 1 + G.randint(size - 2)
        along = G.randint(size)
        agent_low = G.randint(2) == 0
        cells = [(x, y) for x in range(size) for y in range(size)]
        c = 0 if vertical else 1
        low, high = [p for p in cells if p[c] < w], [p for p in cells if p[c] > w]
        agent, other = (low, high) if agent_low else (high, low)
        goal = other[G.randint(len(other))]
        key = agent[G.randint(len(agent))]
        starts = [(x, y, d, 0, 0) for x, y in agent if (x, y) != key for d in range(4)]
        G.shuffle(starts)
        m = jaxmdp.make("MiniGridDoorKey", episodic=False, seed=seed, size=size)
        door = (w, along) if vertical else (along, w)
        assert m.info.layout_value("door") == door
        assert set(m.info.layout_value("walls")) == {(w, i) if vertical else (i, w) for i in range(size)} - {door}
        assert (m.info.layout_value("goal"), m.info.layout_value("key")) == (goal, key)
        P0 = np.asarray(m.P0)
        assert {m.info.node_values[s] for s in np.nonzero(P0)[0]} == set(starts[:2])
        np.testing.assert_allclose(P0[P0 > 0], 0.5)
    m = episodic
    assert m.info.layout_value("door") == (2, 0) and m.info.layout_value("key") == (4, 2)
    assert m.info.layout_value("goal") == (0, 3)
    assert m.info.node_labels[int(np.argmax(m.P0))] == START


def test_pick_up_and_open_work_only_in_front_of_key_and_door(continuous):
    m = continuous
    # facing the key: pick it up; on its other sides or not facing it: nothing happens
    assert row(m, "X=3,Y=2,Dir=RIGHT,HasKey=0,DoorOpen=0", PICK)[0] == {"X=3,Y=2,Dir=RIGHT,HasKey=1,DoorOpen=0": 1.0}
    assert row(m, "X=4,Y=1,Dir=UP,HasKey=0,DoorOpen=0", PICK)[0] == {"X=4,Y=1,Dir=UP,HasKey=1,DoorOpen=0": 1.0}
    assert row(m, "X=3,Y=2,Dir=UP,HasKey=0,DoorOpen=0", PICK)[0] == {"X=3,Y=2,Dir=UP,HasKey=0,DoorOpen=0": 1.0}
    # the key blocks the way while it lies on the floor, not afterwards
    assert row(m, "X=3,Y=2,Dir=RIGHT,HasKey=0,DoorOpen=0", F)[0] == {"X=3,Y=2,Dir=RIGHT,HasKey=0,DoorOpen=0": 1.0}
    assert row(m, "X=3,Y=2,Dir=RIGHT,HasKey=1,DoorOpen=0", F)[0] == {"X=4,Y=2,Dir=RIGHT,HasKey=1,DoorOpen=0": 1.0}
    # the closed door blocks; open needs the key; then the door lets the agent through and never closes
    assert row(m, "X=3,Y=0,Dir=LEFT,HasKey=1,DoorOpen=0", F)[0] == {"X=3,Y=0,Dir=LEFT,HasKey=1,DoorOpen=0": 1.0}
    assert row(m, "X=3,Y=0,Dir=LEFT,HasKey=0,DoorOpen=0", OPEN)[0] == {"X=3,Y=0,Dir=LEFT,HasKey=0,DoorOpen=0": 1.0}
    assert row(m, "X=3,Y=0,Dir=LEFT,HasKey=1,DoorOpen=0", OPEN)[0] == {"X=3,Y=0,Dir=LEFT,HasKey=1,DoorOpen=1": 1.0}
    assert row(m, "X=3,Y=0,Dir=LEFT,HasKey=1,DoorOpen=1", F)[0] == {"X=2,Y=0,Dir=LEFT,HasKey=1,DoorOpen=1": 1.0}
    assert row(m, "X=3,Y=1,Dir=LEFT,HasKey=1,DoorOpen=1", F)[0] == {"X=3,Y=1,Dir=LEFT,HasKey=1,DoorOpen=1": 1.0}
    # rewards follow the next cell
    assert row(m, "X=0,Y=2,Dir=UP,HasKey=1,DoorOpen=1", F) == ({"X=0,Y=3,Dir=UP,HasKey=1,DoorOpen=1": 1.0}, 1.0)
    assert row(m, "X=0,Y=3,Dir=UP,HasKey=1,DoorOpen=1", TL)[1] == 1.0
    # counting: PickUp acts in the 3 states facing the key, Open in exactly one state
    values = m.info.node_values
    T = np.asarray(m.T)
    acts = lambda a: sum(T[s, a, s] < 1 for s in range(m.n_states))  # noqa: E731
    assert (acts(PICK), acts(OPEN)) == (3, 1)
    # flags never go back: no transition lowers HasKey or DoorOpen
    src, _, dst = np.nonzero(T)
    assert all(values[j][3] >= values[i][3] and values[j][4] >= values[i][4] for i, j in zip(src, dst))


@pytest.mark.parametrize("seed, S", [(0, 160), (1, 200), (2, 160), (3, 200), (4, 200), (5, 120)])
def test_state_counts(seed, S):
    # With a rectangular agent room of `a` cells that the key does not split: 4(a-1) states before the key,
    # 4a with the key and the door closed, 4(size^2 - size + 1) with the door open: S = 4 (2a + size (size - 1)).
    m = jaxmdp.make("MiniGridDoorKey", episodic=False, seed=seed, size=5)
    start = m.info.node_values[int(np.argmax(m.P0))]
    walls = set(m.info.layout_value("walls")) | {m.info.layout_value("door")}
    vertical = len({x for x, _ in walls}) == 1
    w = next(iter(walls))[0 if vertical else 1]
    a = 5 * (w if start[0 if vertical else 1] < w else 4 - w)
    assert S == 4 * (2 * a + 5 * 4) and m.n_states == S and m.n_actions == 5


def test_continuous_version_is_weakly_communicating(continuous):
    m = continuous
    assert jaxmdp.communication_class(m) == jaxmdp.CommunicationClass.WEAKLY_COMMUNICATING
    # Independently: the door-open states are closed, reach each other, and every door-closed state is transient
    # (it reaches the door-open states, which never lead back).
    T = np.asarray(m.T)
    succ = [set(np.nonzero(T[s].sum(0))[0]) for s in range(m.n_states)]

    def reach(s):
        seen, todo = {s}, deque([s])
        while todo:
            for j in succ[todo.popleft()] - seen:
                seen.add(j)
                todo.append(j)
        return seen

    is_open = {s for s, v in enumerate(m.info.node_values) if v[4] == 1}
    assert len(is_open) == 4 * (25 - 5 + 1)
    some_open = next(iter(is_open))
    assert reach(some_open) == is_open
    assert all(some_open in reach(s) for s in range(m.n_states))
    lazy = jaxmdp.make("MiniGridDoorKey", episodic=False, seed=0, size=5, p_rand=0.1, p_lazy=0.1)
    assert jaxmdp.communication_class(lazy) == jaxmdp.CommunicationClass.WEAKLY_COMMUNICATING


def test_continuous_optimal_gain_is_the_goal_reward(continuous):
    result = jax.jit(dp.optimal_gain)(continuous.strip())
    assert bool(result.converged)
    np.testing.assert_allclose(result.gain, 1.0, atol=1e-5)


def test_episodic_optimal_return_equals_the_hand_count(episodic):
    m = episodic
    # The default horizon by its definition (docs/families.md §1.8, the module docstring): 1 + the largest
    # shortest-path distance from a possible start, i.e. any node of the agent's room without key, door closed.
    adj = (np.asarray(m.T) > 0).any(1)

    def eccentricity(source):
        dist, queue = {source: 0}, deque([source])
        while queue:
            s = queue.popleft()
            for t in np.flatnonzero(adj[s]):
                if int(t) not in dist:
                    dist[int(t)] = dist[s] + 1
                    queue.append(int(t))
        return max(dist.values())

    possible = [i for i, label in enumerate(m.info.node_labels) if label.endswith("HasKey=0,DoorOpen=0")]
    assert m.H == 1 + max(eccentricity(i) for i in possible)
    T, R = np.asarray(m.T), np.asarray(m.R)
    s = m.info.node_labels.index(START)
    rewards = []
    for a in HAND_PLAN:  # the plan is feasible: deterministic rows, reward only on the last step
        assert T[s, a].max() == 1.0
        rewards.append(R[s, a])
        s = int(np.argmax(T[s, a]))
    assert m.info.node_labels[s] == "X=0,Y=3,Dir=UP,HasKey=1,DoorOpen=1"
    assert rewards == [0.0] * 14 + [1.0]
    # After entering the goal every remaining step pays 1 (turning on the goal); no shorter plan exists iff the optimal
    # return is exactly H - L + 1.
    _, V = dp.finite_horizon_value_iteration(m)
    L = len(HAND_PLAN)
    np.testing.assert_allclose(V[0, m.info.node_labels.index(START)], m.H - L + 1, atol=1e-5)
    # a horizon shorter than the plan earns nothing
    short = jaxmdp.make(
        "MiniGridDoorKey", episodic=True, seed=0, size=5, n_starting_states=1, randomize_actions=False, H=50
    )
    _, V50 = dp.finite_horizon_value_iteration(short, horizon=L - 1)
    assert float(V50[0, short.info.node_labels.index(START)]) == 0.0


def test_randomized_actions_keep_the_optimum():
    m = jaxmdp.make("MiniGridDoorKey", episodic=True, seed=0, size=5, n_starting_states=1)
    assert m.info.node_labels[int(np.argmax(m.P0))] == START
    _, V = dp.finite_horizon_value_iteration(m)
    np.testing.assert_allclose(m.P0 @ V[0], m.H - len(HAND_PLAN) + 1, atol=1e-5)


def test_default_distributions_and_parameters():
    m = jaxmdp.make("MiniGridDoorKey", episodic=False, seed=0, size=4)
    assert m.info.params[6:] == (
        ("size", 4), ("n_starting_states", 2),
        ("optimal_distribution", "Deterministic(1)"), ("other_distribution", "Deterministic(0)"),
    )  # fmt: skip
    s = jaxmdp.make("MiniGridDoorKey", episodic=False, seed=0, size=4, make_reward_stochastic=True)
    assert (s.info.param("optimal_distribution"), s.info.param("other_distribution")) == ("Beta(15, 1)", "Beta(1, 15)")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(size=2), r"size must be an integer >= 3 for MiniGridDoorKey; got 2"),
        (dict(size=5, n_starting_states=0), r"n_starting_states must be an integer in \[1, 16\]"),
        (dict(size=5, n_starting_states=17), r"n_starting_states must be an integer in \[1, 16\] .*got 17"),
        (dict(size=5, optimal_distribution=("deterministic", (1.0,))), "all or none"),
    ],
)
def test_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jaxmdp.make("MiniGridDoorKey", episodic=False, seed=0, **kwargs)


def test_largest_n_starting_states_fits_the_smallest_room():
    # seed 5, size 5: the agent's room is the single row Y = 4 (5 cells, one holding the key)
    m = jaxmdp.make("MiniGridDoorKey", episodic=False, seed=5, size=5, n_starting_states=16)
    assert (np.asarray(m.P0) > 0).sum() == 16


def test_rendering(continuous):
    m = continuous
    lab = m.info.node_labels
    assert jaxmdp.render(m, lab.index(START)).split("\n") == ["  W  ", "G W  ", "  W K", "  W^ ", "  C  "]
    s = lab.index("X=3,Y=0,Dir=LEFT,HasKey=1,DoorOpen=0")
    assert jaxmdp.render(m, s).split("\n") == ["  W  ", "G W  ", "  W  ", "  W  ", "  C< "]
    s = lab.index("X=2,Y=0,Dir=DOWN,HasKey=1,DoorOpen=1")
    assert jaxmdp.render(m, s).split("\n") == ["  W  ", "G W  ", "  W  ", "  W  ", "  v  "]
    s = lab.index("X=1,Y=3,Dir=RIGHT,HasKey=1,DoorOpen=1")
    assert jaxmdp.render(m, s, h=3).split("\n") == ["H=3  ", "_____", "  W  ", "G>W  ", "  W  ", "  W  ", "  O  "]
