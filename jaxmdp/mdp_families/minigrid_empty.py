"""MiniGridEmpty (paper App. C, "MG-Empty"; docs/families.md §2.5).

An empty ``size x size`` grid (cells ``0..size-1``, no wall cells). Nodes are ``(X, Y, Dir)``; actions
``MoveForward`` (clipped at the border: bumping keeps the node), ``TurnRight``, ``TurnLeft`` (see
:mod:`jaxmdp.mdp_families.minigrid`). The optimal reward is paid whenever the next node stands on the goal cell.

Sides of the grid, each listed in a fixed order: side 0 the column ``X = 0`` from ``Y = 0`` up; side 1 the row ``Y = 0``
from ``X = 0`` right; side 2 the column ``X = size-1`` from ``Y = size-1`` down; side 3 the row ``Y = size-1`` from
``X = size-1`` left. Draws from ``G`` in this order: the start side ``k = G.randint(4)``; the goal, cell
``G.randint(size)`` of side ``(k + 2) mod 4``; ``G.shuffle`` of the start side's cells, of which the first
``n_starting_states`` are the starting cells; one direction ``G.randint(4)`` per starting cell. The starting nodes are
uniform. Every cell of the start side in every direction is a *possible* start (used for the horizon, which comes out
as ``2 size + 3``).

The reference renders the MDP's *current* node whatever node is asked for [quirk]; we render the node asked for.
``n_starting_states > size`` is a ``ValueError`` here; the reference silently starts from all ``size`` cells.
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
    MiniGridFamily,
    forward_cell,
    render_minigrid,
    turned,
)
from jaxmdp.render import register_renderer

__all__ = ["MiniGridEmptyNode", "MiniGridEmptyFamily", "minigrid_empty", "side_cells"]


class MiniGridEmptyNode(NamedTuple):
    X: int
    Y: int
    Dir: int


def side_cells(size: int, side: int) -> list[tuple[int, int]]:
    """The ``size`` cells of ``side`` (0 left, 1 bottom, 2 right, 3 top) in the reference's listing order."""
    last = size - 1
    if side == 0:
        return [(0, i) for i in range(size)]
    if side == 1:
        return [(i, 0) for i in range(size)]
    if side == 2:
        return [(last, last - i) for i in range(size)]
    return [(last - i, last) for i in range(size)]


class MiniGridEmptyFamily(MiniGridFamily):
    name = "MiniGridEmpty"
    n_actions = 3
    node_fields = ("X", "Y", "Dir")

    def __init__(
        self,
        *,
        size: int,
        n_starting_states: int,
        rewards: RewardArguments,
    ) -> None:
        self.size = integer_parameter("size", size, 3, self.name)
        self.check_memory()
        # Only the `size` cells of the start side can be starting cells.
        self.n_starting_states = integer_parameter("n_starting_states", n_starting_states, 1, self.name, self.size)
        self.set_rewards(rewards)

    def max_states(self) -> int:
        """The ``size^2`` cells, each in 4 directions."""
        return 4 * self.size**2

    def size_parameters(self) -> dict[str, Any]:
        return {"size": self.size}

    def outcomes(self, node: MiniGridEmptyNode, action: int) -> list[tuple[MiniGridEmptyNode, float]]:
        x, y, d = node
        if action == MOVE_FORWARD:
            nx, ny = forward_cell(x, y, d)
            nx, ny = min(max(nx, 0), self.size - 1), min(max(ny, 0), self.size - 1)
            return [(MiniGridEmptyNode(nx, ny, d), 1.0)]
        return [(MiniGridEmptyNode(x, y, turned(d, action)), 1.0)]

    def starting_nodes(self, G: np.random.RandomState, F: random.Random):
        side = int(G.randint(4))
        self.goal = side_cells(self.size, (side + 2) % 4)[int(G.randint(self.size))]
        cells = side_cells(self.size, side)
        G.shuffle(cells)
        starts = [MiniGridEmptyNode(x, y, int(G.randint(4))) for x, y in cells[: self.n_starting_states]]
        F.randint(0, 10000)  # the reference's starting-sampler seed; keeps F in step
        possible = [MiniGridEmptyNode(x, y, d) for x, y in cells for d in range(4)]
        return starts, [1.0 / len(starts)] * len(starts), possible

    def params(self) -> tuple[tuple[str, Any], ...]:
        return (
            ("size", self.size),
            ("n_starting_states", self.n_starting_states),
            *self.distribution_params(),
        )

    def layout(self) -> tuple[tuple[str, Any], ...]:
        return (("size", self.size), ("goal", self.goal))


def render_minigrid_empty(info: MDPInfo, node: tuple[int, ...]) -> list[list[str]]:
    """``size x size`` blanks, ``G`` at the goal, the agent's arrow (``^ > v <``) over it; top row ``Y = size-1``.

    Symbols ``[" ", ">", "<", "v", "^", "G"]``.
    """
    return render_minigrid(info.layout_value("size"), node, [(info.layout_value("goal"), "G")])


register_renderer(MiniGridEmptyFamily.name, render_minigrid_empty)


@family_builder(MiniGridEmptyFamily)
def minigrid_empty(
    *,
    episodic: bool,
    seed: int,
    size: int,
    n_starting_states: int = 1,
    p_rand: float | None = None,
    p_lazy: float | None = None,
    randomize_actions: bool = True,
    make_reward_stochastic: bool = False,
    reward_variance_multiplier: float = 1.0,
    optimal_distribution: Any = None,
    other_distribution: Any = None,
    H: int | None = None,
) -> MDP:
    """Build a MiniGridEmpty MDP (docs/families.md §2.5): ``S = 4 size^2``, default horizon ``2 size + 3``.

    Args:
      size: grid side, an integer ``>= 3``.
      n_starting_states: number of starting cells on the start side, in ``[1, size]``.
      optimal_distribution, other_distribution: reward distributions (all or none; defaults in
        :meth:`~jaxmdp.mdp_families.minigrid.MiniGridFamily.default_rewards`).
      The other arguments are the common ones (:class:`~jaxmdp.mdp_families.construction.CommonParams`).
    """
