"""Pieces shared by the MiniGrid families (paper App. C "MiniGrid MDPs"; docs/families.md §2.5, §2.6).

The agent stands on a cell ``(X, Y)`` facing a direction ``Dir``: ``UP = 0`` (``Y + 1``), ``RIGHT = 1`` (``X + 1``),
``DOWN = 2`` (``Y - 1``), ``LEFT = 3`` (``X - 1``). Base actions ``0 = MoveForward`` (one cell in the facing
direction when the family admits it), ``1 = TurnRight`` (``Dir + 1 mod 4``) and ``2 = TurnLeft`` (``Dir - 1 mod 4``).
Every MiniGrid family pays its *optimal* reward distribution when the next node stands on the goal cell (whatever the
direction, so turning on the goal keeps paying) and its *other* distribution otherwise; :class:`MiniGridFamily` holds
that reward and the node labels, :func:`render_minigrid` the text grid they all draw.
"""

from __future__ import annotations

from collections.abc import Iterable

from jaxmdp.mdp_families.construction import Family
from jaxmdp.mdp_families.distributions import Beta, Distribution, PointMass, RewardParameters

__all__ = [
    "UP",
    "RIGHT",
    "DOWN",
    "LEFT",
    "DIRECTION_NAMES",
    "MOVE_FORWARD",
    "TURN_RIGHT",
    "TURN_LEFT",
    "ARROWS",
    "forward_cell",
    "turned",
    "MiniGridFamily",
    "render_minigrid",
]

UP, RIGHT, DOWN, LEFT = 0, 1, 2, 3
DIRECTION_NAMES = ("UP", "RIGHT", "DOWN", "LEFT")
MOVE_FORWARD, TURN_RIGHT, TURN_LEFT = 0, 1, 2

#: Text symbol of the agent facing each direction.
ARROWS = ("^", ">", "v", "<")

_DELTA = ((0, 1), (1, 0), (0, -1), (-1, 0))


def forward_cell(x: int, y: int, d: int) -> tuple[int, int]:
    """The cell in front of an agent at ``(x, y)`` facing ``d`` (not clipped)."""
    dx, dy = _DELTA[d]
    return x + dx, y + dy


def turned(d: int, action: int) -> int:
    """The direction after ``TurnRight`` (``d + 1 mod 4``) or ``TurnLeft`` (``d - 1 mod 4``)."""
    return (d + 1) % 4 if action == TURN_RIGHT else (d - 1) % 4


class MiniGridFamily(Family):
    """Base of the MiniGrid families: nodes start with ``(X, Y, Dir)``; subclasses call :meth:`set_rewards` in
    ``__init__`` and set ``self.goal`` when drawing their starting nodes."""

    goal: tuple[int, int] | None = None
    reward_parameters = RewardParameters(distributions=("optimal_distribution", "other_distribution"))

    def default_reward_side(self) -> int:
        """The grid side ``n`` that sizes the stochastic default rewards (:meth:`default_rewards`): ``self.size``."""
        return self.size

    def default_rewards(self, stochastic: bool, v: float) -> tuple[Distribution, ...]:
        """Optimal and other (docs/families.md §2.5): point masses 1 and 0, or ``Beta(v (n^2 - 1), v)`` (mean ``1 -
        1/n^2``) and ``Beta(v, v (n^2 - 1))`` (mean ``1/n^2``) with ``n`` the :meth:`default_reward_side`."""
        if not stochastic:
            return PointMass(1.0), PointMass(0.0)
        n = self.default_reward_side()
        return Beta(v * (n**2 - 1), v), Beta(v, v * (n**2 - 1))

    def reward(self, node: tuple[int, ...], action: int, next_node: tuple[int, ...]) -> Distribution:
        """The optimal distribution when ``next_node`` stands on the goal cell, the other one otherwise."""
        on_goal = (next_node[0], next_node[1]) == self.goal
        return self.dists["optimal_distribution" if on_goal else "other_distribution"]

    def node_label(self, node: tuple[int, ...]) -> str:
        """Colosseum's ``str(node)``: the ``Dir`` field by name (``"X=0,Y=2,Dir=LEFT"``)."""
        return ",".join(f"{f}={DIRECTION_NAMES[v] if f == 'Dir' else v}" for f, v in zip(self.node_fields, node))


def render_minigrid(
    size: int, node: tuple[int, ...], marks: Iterable[tuple[tuple[int, int], str]]
) -> list[list[str]]:
    """A ``size x size`` grid of blanks with ``symbol`` at each ``(x, y)`` of ``marks`` (a later mark covers an earlier
    one) and the agent's arrow (``^ > v <``) on top at ``node``'s ``(X, Y, Dir)``; the top printed row is
    ``Y = size-1``."""
    rows = [[" "] * size for _ in range(size)]
    for (x, y), symbol in marks:
        rows[y][x] = symbol
    x, y, d = node[:3]
    rows[y][x] = ARROWS[d]
    return rows[::-1]
