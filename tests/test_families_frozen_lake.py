"""FrozenLake (docs/families.md §2.4): the random lake, slippery moves, rewards, horizon, validation and rendering."""

from collections import deque

import numpy as np
import pytest

import jaxmdp
from jaxmdp.mdp_families.frozen_lake import random_lake

from jaxmdp.mdp_families import frozen_lake as fl_module

UP, RIGHT, DOWN, LEFT = range(4)


def _make(episodic=False, **kw):
    kw.setdefault("randomize_actions", False)
    return jaxmdp.make("FrozenLake", episodic=episodic, seed=kw.pop("seed", 0), **kw)


def _idx(m, x, y):
    return m.info.node_labels.index(f"X={x},Y={y}")


def _gym_lake(size, p, seed):
    """gym 0.25's generate_random_map written out plainly: one ``choice`` per board, depth-first validity test with
    neighbour order (+1,0), (0,+1), (-1,0), (0,-1); returns the board and the number of boards drawn."""
    rs = np.random.RandomState(seed)
    attempts = 0
    while True:
        attempts += 1
        board = rs.choice(["F", "H"], (size, size), p=[min(1, p), 1 - min(1, p)])
        board[0][0], board[-1][-1] = "S", "G"
        stack, seen = [(0, 0)], set()
        while stack:
            r, c = stack.pop()
            if (r, c) in seen:
                continue
            seen.add((r, c))
            for dr, dc in ((1, 0), (0, 1), (-1, 0), (0, -1)):
                rn, cn = r + dr, c + dc
                if 0 <= rn < size and 0 <= cn < size:
                    if board[rn][cn] == "G":
                        return tuple("".join(row) for row in board), attempts
                    if board[rn][cn] != "H":
                        stack.append((rn, cn))


def test_worked_example_size_4_seed_0():
    m = _make(size=4, p_frozen=0.8)
    assert m.info.layout_value("lake") == ("SFFF", "FFFH", "HFFF", "FHFG")
    assert m.n_states == 12
    assert m.info.node_labels == tuple(
        f"X={x},Y={y}"
        for x, y in [(0, 0), (0, 1), (0, 2), (0, 3), (1, 2), (1, 1), (1, 0), (2, 1), (2, 2), (2, 3), (3, 3), (3, 2)]
    )
    T, R = np.asarray(m.T), np.asarray(m.R)
    s00, s01, s10 = _idx(m, 0, 0), _idx(m, 0, 1), _idx(m, 1, 0)
    for a, row in {
        UP: {s00: 0.75, s01: 0.25},
        RIGHT: {s00: 0.75, s10: 0.25},
        DOWN: {s00: 0.25, s01: 0.25, s10: 0.5},
        LEFT: {s00: 0.25, s01: 0.5, s10: 0.25},
    }.items():
        expected = np.zeros(12)
        for t, p in row.items():
            expected[t] = p
        np.testing.assert_allclose(T[s00, a], expected, atol=1e-7)
    assert np.all(R[s00] == 0)


@pytest.mark.parametrize("size,p", [(3, 0.5), (4, 0.8), (5, 0.6), (6, 0.5), (8, 0.9), (4, 1.3)])
def test_lake_matches_gym_routine_including_rejections(size, p):
    rejected = 0
    for seed in range(12):
        board, attempts = _gym_lake(size, p, seed)
        assert random_lake(size, p, seed) == board
        rejected += attempts > 1
    if p < 0.7:
        assert rejected > 0  # the batched draw must agree after rejected boards too


def test_lake_generation_leaves_numpy_global_generator_alone():
    np.random.seed(123)
    before = np.random.get_state()[1].copy()
    _make(size=5, p_frozen=0.7, seed=4)
    np.testing.assert_array_equal(np.random.get_state()[1], before)


@pytest.mark.parametrize("size,counts", [(3, [8, 9, 9]), (4, [12, 15, 16]), (5, [19, 22, 23])])
def test_state_counts_p_frozen_08(size, counts):
    assert [_make(size=size, p_frozen=0.8, seed=s).n_states for s in range(3)] == counts


def _bfs_eccentricity(T, source):
    adj = (np.asarray(T) > 0).any(1)
    dist = {source: 0}
    queue = deque([source])
    while queue:
        s = queue.popleft()
        for t in np.flatnonzero(adj[s]):
            if t not in dist:
                dist[int(t)] = dist[s] + 1
                queue.append(int(t))
    return max(dist.values())


def _board_eccentricity(lake) -> int:
    """The largest number of moves from (0, 0) to a state, on the board alone (the family's definition: slippery
    moves reach the four neighbours, holes are not states, the goal only leads back to the start)."""
    n = len(lake)
    dist, queue = {(0, 0): 0}, deque([(0, 0)])
    while queue:
        x, y = queue.popleft()
        if lake[x][y] == "G":
            continue
        for nx, ny in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)):
            if 0 <= nx < n and 0 <= ny < n and lake[nx][ny] != "H" and (nx, ny) not in dist:
                dist[(nx, ny)] = dist[(x, y)] + 1
                queue.append((nx, ny))
    return max(dist.values())


@pytest.mark.parametrize("size,p,seed", [(4, 0.95, 0), (5, 0.9, 3), (6, 0.85, 4), (3, 0.8, 1)])
def test_default_horizon_is_one_plus_the_eccentricity_of_the_start(size, p, seed):
    # Expected values from the family's definition (docs/families.md §1.8: 1 + eccentricity of (0, 0)), computed on
    # the drawn board and on the built kernel's graph.
    m = _make(episodic=True, size=size, p_frozen=p, seed=seed)
    assert m.H == 1 + _board_eccentricity(m.info.layout_value("lake")) == 1 + _bfs_eccentricity(m.T, _idx(m, 0, 0))


def test_states_are_the_reachable_non_hole_cells_and_holes_send_back_to_start():
    m = _make(size=6, p_frozen=0.7, seed=5)
    lake = m.info.layout_value("lake")
    cells = {tuple(v) for v in m.info.node_values}
    assert all(lake[x][y] != "H" for x, y in cells)
    # Independent flood fill on the board; the goal only leads back to the start, so cells behind it are not states.
    seen, queue = {(0, 0)}, deque([(0, 0)])
    while queue:
        x, y = queue.popleft()
        if lake[x][y] == "G":
            continue
        for nx, ny in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)):
            if 0 <= nx < 6 and 0 <= ny < 6 and lake[nx][ny] != "H" and (nx, ny) not in seen:
                seen.add((nx, ny))
                queue.append((nx, ny))
    assert cells == seen
    assert lake[5][4] != "H" and (5, 4) not in cells  # this lake has a frozen cell reachable only through G
    T = np.asarray(m.T)
    s00 = _idx(m, 0, 0)
    for x, y in cells:
        for a, (dx, dy) in {UP: (-1, 0), RIGHT: (0, -1), DOWN: (1, 0), LEFT: (0, 1)}.items():
            if lake[x][y] == "G":
                continue
            tx, ty = min(max(x + dx, 0), 5), min(max(y + dy, 0), 5)
            target = s00 if lake[tx][ty] == "H" else _idx(m, tx, ty)
            assert T[_idx(m, x, y), a, target] >= 0.5 - 1e-7  # the intended move carries at least 1/2


def test_goal_rewards_and_return_to_start():
    m = _make(size=4, p_frozen=0.8)
    T, R = np.asarray(m.T), np.asarray(m.R)
    g, s00, s32, s23 = _idx(m, 3, 3), _idx(m, 0, 0), _idx(m, 3, 2), _idx(m, 2, 3)
    np.testing.assert_allclose(T[g], np.tile(np.eye(12)[s00], (4, 1)), atol=1e-7)
    assert np.all(R[g] == 0)  # leaving the goal pays the default reward
    # From (3, 2): LEFT (Y+1) reaches G with 1/2; UP and DOWN slip into LEFT with 1/4; RIGHT never does.
    np.testing.assert_allclose(R[s32], [0.25, 0.0, 0.25, 0.5], atol=1e-7)
    np.testing.assert_allclose(T[s32, LEFT, g], 0.5, atol=1e-7)
    # From (2, 3): DOWN (X+1) reaches G.
    assert R[s23, DOWN] == pytest.approx(0.5)


def test_not_slippery_is_deterministic():
    m = _make(size=4, p_frozen=0.8, is_slippery=False)
    T = np.asarray(m.T)
    assert np.all((T == 0) | (T == 1))
    s00 = _idx(m, 0, 0)
    assert T[s00, DOWN, _idx(m, 1, 0)] == 1 and T[s00, LEFT, _idx(m, 0, 1)] == 1 and T[s00, UP, s00] == 1
    assert dict(m.info.params)["is_slippery"] is False


@pytest.mark.parametrize("size,v,goal,default", [(3, 1.0, (8, 1), (1, 89)), (4, 1.0, (15, 1), (1, 159)),
                                                 (4, 2.0, (30, 2), (2, 318))])
def test_stochastic_default_distributions(size, v, goal, default):
    m = _make(size=size, p_frozen=0.8, make_reward_stochastic=True, reward_variance_multiplier=v)
    params = dict(m.info.params)
    assert params["goal_r"] == f"Beta({goal[0]:g}, {goal[1]:g})"
    assert params["default_r"] == f"Beta({default[0]:g}, {default[1]:g})"
    mean, conc = np.asarray(m.reward_mean), np.asarray(m.reward_conc)
    g, s00 = _idx(m, size - 1, size - 1), _idx(m, 0, 0)
    assert conc[g, 0, s00] == pytest.approx(sum(default))
    assert mean[g, 0, s00] == pytest.approx(default[0] / sum(default))
    into_goal = np.argwhere(np.asarray(m.T)[:, :, g] > 0)[0]
    assert conc[into_goal[0], into_goal[1], g] == pytest.approx(sum(goal))
    assert mean[into_goal[0], into_goal[1], g] == pytest.approx(goal[0] / sum(goal))


def test_parameter_order():
    m = _make(size=3, p_frozen=0.9, seed=2, p_lazy=0.1)
    assert m.info.params == (
        ("seed", 2),
        ("randomize_actions", False),
        ("p_lazy", 0.1),
        ("p_rand", None),
        ("make_reward_stochastic", False),
        ("reward_variance_multiplier", 1.0),
        ("size", 3),
        ("p_frozen", 0.9),
        ("optimal_return", 1.0),
        ("suboptimal_return", 0.1),
        ("is_slippery", True),
        ("goal_r", "Deterministic(1)"),
        ("default_r", "Deterministic(0)"),
    )


def test_validation_errors(monkeypatch):
    with pytest.raises(ValueError, match="size must be an integer >= 3"):
        _make(size=2, p_frozen=0.8)
    with pytest.raises(ValueError, match="p_frozen must be a number >= 0.1"):
        _make(size=4, p_frozen=0.05)
    with pytest.raises(ValueError, match="suboptimal_return \\+ 0.2 must be below optimal_return"):
        _make(size=4, p_frozen=0.8, suboptimal_return=0.85)
    with pytest.raises(ValueError, match="is_slippery must be True or False"):
        _make(size=4, p_frozen=0.8, is_slippery=1)
    with pytest.raises(ValueError, match="all or none"):
        _make(size=4, p_frozen=0.8, goal_r=("deterministic", (1.0,)))
    with pytest.raises(ValueError, match=r"optimal_return must lie in \(0, size\^2=9\)"):
        _make(size=3, p_frozen=0.8, make_reward_stochastic=True, optimal_return=10.0)
    with pytest.raises(TypeError):
        jaxmdp.make("FrozenLake", episodic=False, seed=0, size=4)  # p_frozen is required
    # A lake whose goal can never be reached in practice is an error, not a hang.
    monkeypatch.setattr(fl_module, "MAX_LAKE_DRAWS", 1000)
    with pytest.raises(ValueError, match="p_frozen=0.1 is too low for size=10"):
        _make(size=10, p_frozen=0.1)


def test_rendering_transposes_and_reverses():
    m = _make(size=4, p_frozen=0.8)
    # Board rows X: SFFF / FFFH / HFFF / FHFG; printed row r is Y = 3 - r, printed column c is X; S shows as F.
    assert jaxmdp.render(m, _idx(m, 1, 1)).split("\n") == ["FHFG", "FFFF", "FAFH", "FFHF"]
    assert jaxmdp.render(m, _idx(m, 0, 0)).split("\n") == ["FHFG", "FFFF", "FFFH", "AFHF"]
    assert jaxmdp.render(m, _idx(m, 3, 3)).split("\n")[0] == "FHFA"
    e = _make(episodic=True, size=4, p_frozen=0.8)
    assert jaxmdp.render(e, 0, h=12).split("\n")[:3] == ["H=12", "____", "FHFG"]
