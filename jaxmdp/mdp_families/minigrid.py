"""Pieces shared by the MiniGrid families (paper App. C "MiniGrid MDPs"; families.md §2.5, §2.6).

The agent stands on a cell ``(X, Y)`` facing a direction ``Dir``: ``UP = 0`` (``Y + 1``), ``RIGHT = 1`` (``X + 1``),
``DOWN = 2`` (``Y - 1``), ``LEFT = 3`` (``X - 1``). Base actions ``0 = MoveForward`` (one cell in the facing
direction when the family admits it), ``1 = TurnRight`` (``Dir + 1 mod 4``) and ``2 = TurnLeft`` (``Dir - 1 mod 4``).
Every MiniGrid family pays its *optimal* reward distribution when the next node stands on the goal cell (whatever the
direction, so turning on the goal keeps paying) and its *other* distribution otherwise.
"""

from __future__ import annotations

from typing import Any

from jaxmdp.mdp_families.distributions import Beta, Distribution, PointMass, resolve_distributions

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
    "minigrid_label",
    "minigrid_distributions",
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


def minigrid_label(fields: tuple[str, ...], node: tuple[int, ...]) -> str:
    """Colosseum's ``str(node)`` for MiniGrid nodes: the ``Dir`` field by name (``"X=0,Y=2,Dir=LEFT"``)."""
    return ",".join(
        f"{f}={DIRECTION_NAMES[v] if f == 'Dir' else v}" for f, v in zip(fields, node)
    )


def minigrid_distributions(
    size: int,
    make_reward_stochastic: bool,
    reward_variance_multiplier: float,
    optimal_distribution: Any,
    other_distribution: Any,
) -> dict[str, Distribution]:
    """The optimal / other reward distributions (families.md §2.5).

    Defaults: point masses 1 and 0; stochastic ``Beta(v (size^2 - 1), v)`` (mean ``1 - 1/size^2``) and
    ``Beta(v, v (size^2 - 1))`` (mean ``1/size^2``) with ``v = reward_variance_multiplier``. Explicit distributions
    are taken all or none and must match ``make_reward_stochastic``.
    """
    v = reward_variance_multiplier

    def defaults() -> dict[str, Distribution]:
        if not make_reward_stochastic:
            return {"optimal_distribution": PointMass(1.0), "other_distribution": PointMass(0.0)}
        return {
            "optimal_distribution": Beta(v * (size**2 - 1), v),
            "other_distribution": Beta(v, v * (size**2 - 1)),
        }

    given = {"optimal_distribution": optimal_distribution, "other_distribution": other_distribution}
    return resolve_distributions(given, defaults, make_reward_stochastic)
