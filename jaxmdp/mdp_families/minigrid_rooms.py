"""MiniGridRooms (paper App. C, "MG-Rooms"; docs/families.md §2.6).

``k x k`` square rooms (``k = sqrt(n_rooms)``) of ``rs x rs`` cells (``rs = room_size``) separated by one-cell walls
with a door in the middle of every room span. Room ``(rx, ry)`` holds the cells ``(i + (rs+1) rx, j + (rs+1) ry)``,
``0 <= i, j < rs``; the wall lines lie at ``w = j (rs+1) - 1`` (``j = 1..k-1``) and the doors at ``(w, m)`` and
``(m, w)`` with ``m = j (rs+1) + floor(rs/2)`` (``j = 0..k-1``). The grid side is ``k rs + k - 1``. Nodes are
``(X, Y, Dir)``; ``MoveForward`` enters the facing cell only when it is a room or door cell (walls and the border
block), the turns are as in every MiniGrid family (:mod:`jaxmdp.mdp_families.minigrid`). The optimal reward is paid
whenever the next node stands on the goal cell.

Draws, in order: the start room ``F.randint(0, 3)`` among the corner rooms ``[(0,0), (0,k-1), (k-1,0), (k-1,k-1)]``,
which is removed; the goal room ``F.randint(0, 2)`` among the remaining three; ``G.shuffle`` of the goal room's cells
(listed ``j = rs-1..0`` outer, ``i = 0..rs-1`` inner), whose first cell is the goal; ``G.shuffle`` of the start room's
``(cell, Dir)`` pairs (cells in the same listing, ``Dir = 0..3`` inner). That shuffled list is the set of *possible*
starts (it fixes the horizon ``2 k (rs+1) + 3``); its first ``n_starting_states`` entries are the uniform starts.

The reference renders the MDP's *current* node whatever node is asked for [quirk]; we render the node asked for.
``n_starting_states > 4 rs^2`` is a ``ValueError`` here; the reference builds a starting distribution whose
probabilities do not match its nodes.
"""

from __future__ import annotations

import math
import random
from typing import Any, NamedTuple

import numpy as np

from jaxmdp.mdp import MDP, MDPInfo
from jaxmdp.mdp_families.construction import family_builder, integer_parameter
from jaxmdp.mdp_families.distributions import RewardArguments
from jaxmdp.mdp_families.minigrid import (
    MOVE_FORWARD,
    MiniGridFamily,
    forward_cell,
    render_minigrid,
    turned,
)
from jaxmdp.render import register_renderer

__all__ = ["MiniGridRoomsNode", "MiniGridRoomsFamily", "minigrid_rooms", "room_cells", "admissible_cells"]


class MiniGridRoomsNode(NamedTuple):
    X: int
    Y: int
    Dir: int


def room_cells(room_size: int, room: tuple[int, int]) -> list[tuple[int, int]]:
    """Cells of room ``(rx, ry)`` in the reference's listing order (``j = rs-1..0`` outer, ``i = 0..rs-1`` inner)."""
    rx, ry = room
    step = room_size + 1
    return [(i + step * rx, j + step * ry) for j in reversed(range(room_size)) for i in range(room_size)]


def admissible_cells(room_size: int, k: int) -> frozenset[tuple[int, int]]:
    """Room cells and door cells of a ``k x k`` rooms layout."""
    cells = {c for rx in range(k) for ry in range(k) for c in room_cells(room_size, (rx, ry))}
    walls = [j * (room_size + 1) - 1 for j in range(1, k)]
    middles = [j * (room_size + 1) + room_size // 2 for j in range(k)]
    cells.update((w, m) for w in walls for m in middles)
    cells.update((m, w) for m in middles for w in walls)
    return frozenset(cells)


class MiniGridRoomsFamily(MiniGridFamily):
    name = "MiniGridRooms"
    n_actions = 3
    node_fields = ("X", "Y", "Dir")

    def __init__(
        self,
        *,
        room_size: int,
        n_rooms: int,
        n_starting_states: int,
        rewards: RewardArguments,
    ) -> None:
        self.room_size = integer_parameter("room_size", room_size, 2, self.name)
        is_int = isinstance(n_rooms, (int, np.integer)) and not isinstance(n_rooms, (bool, np.bool_))
        if not (is_int and n_rooms >= 4 and math.isqrt(int(n_rooms)) ** 2 == n_rooms):
            raise ValueError(f"n_rooms must be a perfect square >= 4 (4, 9, 16, ...) for {self.name}; got {n_rooms!r}")
        self.n_rooms = int(n_rooms)
        k = math.isqrt(self.n_rooms)
        self.k = k
        # The starting nodes are drawn among the start room's cells x 4 directions.
        self.n_starting_states = integer_parameter(
            "n_starting_states", n_starting_states, 1, self.name, 4 * self.room_size**2
        )
        self.side = k * self.room_size + k - 1
        self.check_memory()
        self.cells = admissible_cells(self.room_size, k)
        self.set_rewards(rewards)

    def max_states(self) -> int:
        """The admissible cells (:func:`admissible_cells`: ``k^2 room_size^2`` room cells and ``2 k (k - 1)`` doors),
        each in 4 directions."""
        k = self.k
        return 4 * (k * k * self.room_size**2 + 2 * k * (k - 1))

    def size_parameters(self) -> dict[str, Any]:
        return {"room_size": self.room_size, "n_rooms": self.n_rooms}

    def default_reward_side(self) -> int:
        """The room cells per side, walls excluded: the side that the reference sizes the default rewards with."""
        return int(self.room_size * math.sqrt(self.n_rooms))

    def outcomes(self, node: MiniGridRoomsNode, action: int) -> list[tuple[MiniGridRoomsNode, float]]:
        x, y, d = node
        if action == MOVE_FORWARD:
            nxt = forward_cell(x, y, d)
            return [(MiniGridRoomsNode(*nxt, d) if nxt in self.cells else node, 1.0)]
        return [(MiniGridRoomsNode(x, y, turned(d, action)), 1.0)]

    def starting_nodes(self, G: np.random.RandomState, F: random.Random):
        last = self.k - 1
        corners = [(0, 0), (0, last), (last, 0), (last, last)]
        start_room = corners.pop(F.randint(0, 3))
        goal_room = corners[F.randint(0, 2)]
        goal_cells = room_cells(self.room_size, goal_room)
        G.shuffle(goal_cells)
        self.goal = goal_cells[0]
        possible = [MiniGridRoomsNode(x, y, d) for x, y in room_cells(self.room_size, start_room) for d in range(4)]
        G.shuffle(possible)
        F.randint(0, 10000)  # the reference's starting-sampler seed; keeps F in step
        starts = possible[: self.n_starting_states]
        return starts, [1.0 / len(starts)] * len(starts), possible

    def params(self) -> tuple[tuple[str, Any], ...]:
        return (
            ("room_size", self.room_size),
            ("n_rooms", self.n_rooms),
            ("n_starting_states", self.n_starting_states),
            *self.distribution_params(),
        )

    def layout(self) -> tuple[tuple[str, Any], ...]:
        return (("room_size", self.room_size), ("rooms_per_side", self.k), ("side", self.side), ("goal", self.goal))


def render_minigrid_rooms(info: MDPInfo, node: tuple[int, ...]) -> list[list[str]]:
    """Grid of side ``g = k rs + k - 1``: ``W`` on wall cells, ``G`` at the goal, the agent's arrow over it; the top
    printed row is ``Y = g-1`` (docs/families.md §2.6). Symbols ``[" ", ">", "<", "v", "^", "G", "W"]``.

    With 1-based ``x, y`` and door coordinates ``D = {floor(rs/2) + i (rs+1) + 1}``, a cell is a wall when
    (``x != g``, ``x mod (rs+1) = 0``, ``y not in D``) or (``y != g``, ``y mod (rs+1) = 0``, ``x not in D``).
    """
    rs, k, g = (info.layout_value(n) for n in ("room_size", "rooms_per_side", "side"))
    doors = {rs // 2 + i * (rs + 1) + 1 for i in range(k)}
    walls = [
        ((x - 1, y - 1), "W")
        for x in range(1, g + 1)
        for y in range(1, g + 1)
        if (x != g and x % (rs + 1) == 0 and y not in doors) or (y != g and y % (rs + 1) == 0 and x not in doors)
    ]
    return render_minigrid(g, node, [*walls, (info.layout_value("goal"), "G")])


register_renderer(MiniGridRoomsFamily.name, render_minigrid_rooms)


@family_builder(MiniGridRoomsFamily)
def minigrid_rooms(
    *,
    episodic: bool,
    seed: int,
    room_size: int,
    n_rooms: int = 4,
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
    """Build a MiniGridRooms MDP (docs/families.md §2.6): ``S = 4 (n_rooms rs^2 + 2 k (k-1))``, default horizon
    ``2 k (rs+1) + 3``.

    Args:
      room_size: side ``rs`` of a room, an integer ``>= 2``.
      n_rooms: number of rooms, a perfect square ``>= 4``.
      n_starting_states: number of starting nodes, in ``[1, 4 rs^2]``.
      optimal_distribution, other_distribution: reward distributions (all or none); the defaults are MiniGridEmpty's
        with ``size = int(rs sqrt(n_rooms))``.
      The other arguments are the common ones (:class:`~jaxmdp.mdp_families.construction.CommonParams`).
    """
