"""MiniGridDoorKey (paper App. C, "MG-DoorKey"): a new family designed from the paper; Colosseum 1.2 has none.

**Layout.** A ``size x size`` grid (cells ``0..size-1``, no outer wall cells, as in MiniGridEmpty) is split by one full
wall line with a single door. Draws from ``G``, in order:

1. ``G.randint(2)``: the wall is vertical (``0``, the cells ``X = w``) or horizontal (``1``, the cells ``Y = w``);
2. ``w = 1 + G.randint(size - 2)``, so both rooms are non-empty;
3. ``G.randint(size)``: the door's position along the wall;
4. ``G.randint(2)``: the agent's room is the low side (``0``, coordinate ``< w``) or the high side (``1``);
5. the goal: cell ``G.randint(n)`` of the other room's ``n`` cells, listed row-major (``X`` outer, ``Y`` inner);
6. the key: cell ``G.randint(n)`` of the agent room's ``n`` cells, in the same listing;
7. ``G.shuffle`` of the list of ``(cell, Dir)`` for the agent room's cells other than the key (``Dir = 0..3``
   inner), all without key and with the door closed. This list is the set of *possible* starts (it fixes the default
   horizon); its first ``n_starting_states`` entries are the uniform starting nodes.

**Nodes** ``(X, Y, Dir, HasKey, DoorOpen)`` with ``HasKey, DoorOpen in {0, 1}``: the key never moves while on the
floor and cannot be dropped, so a flag for it and one for the door make the dynamics Markov. Reachable combinations
are ``(0, 0)``, ``(1, 0)`` and ``(1, 1)``.

**Actions (5)**: ``0 MoveForward``, ``1 TurnRight``, ``2 TurnLeft`` (as in every MiniGrid family, see
:mod:`jaxmdp.mdp_families.minigrid`), ``3 PickUp``, ``4 Open``. MoveForward enters the facing cell unless it is outside
the grid, a wall cell, the door while closed, or the key cell while the key lies there (objects block, as in
MiniGrid). PickUp sets ``HasKey = 1`` when the key lies on the floor in the facing cell ("in front of", paper). Open sets
``DoorOpen = 1`` when carrying the key and facing the closed door; the door never closes again and the key is kept.
Every other case leaves the node unchanged. All transitions are deterministic (before ``p_rand``/``p_lazy``).

**Rewards**: the optimal distribution when the next node stands on the goal cell (turning on the goal keeps paying), the
other distribution otherwise; defaults as MiniGridEmpty (point masses 1 / 0; stochastic ``Beta(v (size^2-1), v)`` /
``Beta(v, v (size^2-1))``).

**Structure.** The door-open states form the only closed class: every door-closed state is transient, so the continuous
MDP is weakly communicating (paper App. C and §5: the reason the family was left out of the hyperparameter search).
Without ``p_rand``/``p_lazy``, the episodic optimal return from a start is ``H - L + 1`` where ``L`` is the length of
the shortest action sequence that enters the goal (afterwards turning on the goal pays every step).

**Departures from the legacy v1.0 implementation** (docs/families.md §2.8; not reproduced, only described): v1.0 had six
actions (an extra DropObject), picked the key up when standing *on* its cell and let the agent walk over it, tracked the
key's position ``(XKey, YKey)`` because it could be dropped, and drew its layout with its own random stream. Here the
action set is the paper's five, pick-up works from the facing cell, the key blocks movement until picked up, and the
draws are the ones listed above. As in v1.0 (and as in the paper) the key lies in the agent's room, the goal in the
other one, the door opens only with the key and never closes, and two starting nodes are the default.

Rendering (paper): ``>,v,<,^`` the agent, ``K`` the key while on the floor, ``C`` / ``O`` the closed / open door,
``G`` the goal, ``W`` the wall; the top printed row is ``Y = size-1``.
"""

from __future__ import annotations

import random
from typing import Any, NamedTuple

import numpy as np

from jaxmdp.mdp import MDP, MDPInfo
from jaxmdp.mdp_families.construction import family_builder, integer_parameter
from jaxmdp.mdp_families.distributions import RewardArguments
from jaxmdp.mdp_families.minigrid import (
    MOVE_FORWARD,
    TURN_LEFT,
    TURN_RIGHT,
    MiniGridFamily,
    forward_cell,
    render_minigrid,
    turned,
)
from jaxmdp.render import register_renderer

__all__ = ["MiniGridDoorKeyNode", "MiniGridDoorKeyFamily", "minigrid_doorkey", "PICK_UP", "OPEN"]

PICK_UP, OPEN = 3, 4


class MiniGridDoorKeyNode(NamedTuple):
    X: int
    Y: int
    Dir: int
    HasKey: int
    DoorOpen: int


class MiniGridDoorKeyFamily(MiniGridFamily):
    name = "MiniGridDoorKey"
    n_actions = 5
    node_fields = ("X", "Y", "Dir", "HasKey", "DoorOpen")

    def __init__(
        self,
        *,
        size: int,
        n_starting_states: int,
        rewards: RewardArguments,
    ) -> None:
        self.size = integer_parameter("size", size, 3, self.name)
        self.check_memory()
        # The smallest agent room is one line of `size` cells, one of which holds the key.
        self.n_starting_states = integer_parameter(
            "n_starting_states", n_starting_states, 1, self.name, 4 * (self.size - 1)
        )
        self.set_rewards(rewards)
        self.walls: frozenset[tuple[int, int]] = frozenset()
        self.door: tuple[int, int] = (-1, -1)
        self.key: tuple[int, int] = (-1, -1)
        self.goal: tuple[int, int] = (-1, -1)

    def max_states(self) -> int:
        """4 directions on: the agent room's cells without and with the key while the door is closed (each room holds
        at most ``size (size - 2)`` cells), and every cell but the wall's ``size - 1`` once it is open."""
        size = self.size
        return 4 * (2 * size * (size - 2) + size**2 - (size - 1))

    def size_parameters(self) -> dict[str, Any]:
        return {"size": self.size}

    def _draw_layout(self, G: np.random.RandomState) -> list[tuple[int, int]]:
        """Steps 1-6 of the module docstring; returns the agent room's cells."""
        size = self.size
        vertical = int(G.randint(2)) == 0
        w = 1 + int(G.randint(size - 2))
        along = int(G.randint(size))
        agent_low = int(G.randint(2)) == 0
        line = [(w, i) if vertical else (i, w) for i in range(size)]
        self.door = line[along]
        self.walls = frozenset(line) - {self.door}
        cells = [(x, y) for x in range(size) for y in range(size)]
        coord = (lambda c: c[0]) if vertical else (lambda c: c[1])
        low = [c for c in cells if coord(c) < w]
        high = [c for c in cells if coord(c) > w]
        agent_room, goal_room = (low, high) if agent_low else (high, low)
        self.goal = goal_room[int(G.randint(len(goal_room)))]
        self.key = agent_room[int(G.randint(len(agent_room)))]
        return agent_room

    def outcomes(self, node: MiniGridDoorKeyNode, action: int) -> list[tuple[MiniGridDoorKeyNode, float]]:
        x, y, d, has_key, door_open = node
        if action in (TURN_RIGHT, TURN_LEFT):
            return [(MiniGridDoorKeyNode(x, y, turned(d, action), has_key, door_open), 1.0)]
        front = forward_cell(x, y, d)
        if action == MOVE_FORWARD:
            blocked = (
                not (0 <= front[0] < self.size and 0 <= front[1] < self.size)
                or front in self.walls
                or (front == self.door and not door_open)
                or (front == self.key and not has_key)
            )
            if not blocked:
                return [(MiniGridDoorKeyNode(*front, d, has_key, door_open), 1.0)]
        elif action == PICK_UP and not has_key and front == self.key:
            return [(MiniGridDoorKeyNode(x, y, d, 1, door_open), 1.0)]
        elif action == OPEN and has_key and not door_open and front == self.door:
            return [(MiniGridDoorKeyNode(x, y, d, has_key, 1), 1.0)]
        return [(node, 1.0)]

    def starting_nodes(self, G: np.random.RandomState, F: random.Random):
        agent_room = self._draw_layout(G)
        possible = [MiniGridDoorKeyNode(x, y, d, 0, 0) for x, y in agent_room if (x, y) != self.key for d in range(4)]
        G.shuffle(possible)
        starts = possible[: self.n_starting_states]
        return starts, [1.0 / len(starts)] * len(starts), possible

    def params(self) -> tuple[tuple[str, Any], ...]:
        return (
            ("size", self.size),
            ("n_starting_states", self.n_starting_states),
            *self.distribution_params(),
        )

    def layout(self) -> tuple[tuple[str, Any], ...]:
        return (
            ("size", self.size),
            ("walls", tuple(sorted(self.walls))),
            ("door", self.door),
            ("key", self.key),
            ("goal", self.goal),
        )


def render_minigrid_doorkey(info: MDPInfo, node: tuple[int, ...]) -> list[list[str]]:
    """``W`` walls, ``C``/``O`` the closed/open door, ``K`` the key while on the floor, ``G`` the goal and the agent's
    arrow (``^ > v <``) on top; the top printed row is ``Y = size-1``.
    Symbols ``[" ", ">", "<", "v", "^", "G", "W", "K", "C", "O"]``."""
    has_key, door_open = node[3], node[4]
    marks = [(cell, "W") for cell in info.layout_value("walls")]
    marks.append((info.layout_value("door"), "O" if door_open else "C"))
    if not has_key:
        marks.append((info.layout_value("key"), "K"))
    marks.append((info.layout_value("goal"), "G"))
    return render_minigrid(info.layout_value("size"), node, marks)


register_renderer(MiniGridDoorKeyFamily.name, render_minigrid_doorkey)


@family_builder(MiniGridDoorKeyFamily)
def minigrid_doorkey(
    *,
    episodic: bool,
    seed: int,
    size: int,
    n_starting_states: int = 2,
    p_rand: float | None = None,
    p_lazy: float | None = None,
    randomize_actions: bool = True,
    make_reward_stochastic: bool = False,
    reward_variance_multiplier: float = 1.0,
    optimal_distribution: Any = None,
    other_distribution: Any = None,
    H: int | None = None,
) -> MDP:
    """Build a MiniGridDoorKey MDP (see the module docstring). Default horizon: ``1 +`` the largest shortest-path
    distance from a possible start (docs/families.md §1.8), which covers fetching the key, opening the door and reaching
    the farthest cell.

    Args:
      size: grid side, an integer ``>= 3``.
      n_starting_states: number of starting nodes, in ``[1, 4 (size - 1)]`` (the smallest agent room is one line of
        ``size`` cells, one of which holds the key).
      optimal_distribution, other_distribution: reward distributions (all or none; defaults as MiniGridEmpty).
      The other arguments are the common ones (:class:`~jaxmdp.mdp_families.construction.CommonParams`).
    """
