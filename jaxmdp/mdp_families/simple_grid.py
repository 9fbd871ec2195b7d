"""SimpleGrid (paper App. C; docs/families.md §2.3).

A ``size x size`` grid of cells ``(X, Y)`` with five deterministic actions UP (``Y+1``), RIGHT (``X+1``), DOWN
(``Y-1``), LEFT (``X-1``) and NO_OP, clipped at the border. Staying in a corner (a *corner loop*: NO_OP, bumping into
the wall or the lazy self-loop) pays the optimal or the sub-optimal reward depending on ``reward_type``; every other
transition pays the "other" reward. The agent starts near the centre.
"""

from __future__ import annotations

import enum
import random
from typing import Any, NamedTuple

import numpy as np

from jaxmdp.mdp import MDP, MDPInfo
from jaxmdp.mdp_families.construction import Family, family_builder, integer_parameter
from jaxmdp.mdp_families.distributions import (
    Distribution,
    PointMass,
    RewardArguments,
    RewardParameters,
    beta_with_mean,
    check_default_reward_parameter,
)
from jaxmdp.render import register_renderer

__all__ = ["SimpleGridNode", "SimpleGridReward", "SimpleGridFamily", "simple_grid"]

UP, RIGHT, DOWN, LEFT, NO_OP = 0, 1, 2, 3, 4


class SimpleGridReward(enum.IntEnum):
    """Which corner loops pay the optimal reward (integer truthiness of the corner's coordinates)."""

    AND = 0  # X != 0 and Y != 0: only (size-1, size-1)
    NAND = 1  # not (X != 0 and Y != 0): every corner but (size-1, size-1)
    OR = 2  # X | Y != 0: every corner but (0, 0)
    XOR = 3  # X ^ Y != 0: (size-1, 0) and (0, size-1)

    def is_good(self, x: int, y: int) -> bool:
        """Whether the corner loop at ``(x, y)`` pays the optimal distribution."""
        if self is SimpleGridReward.AND:
            return bool(x and y)
        if self is SimpleGridReward.NAND:
            return not (x and y)
        if self is SimpleGridReward.OR:
            return bool(x | y)
        return bool(x ^ y)


def _reward_type(value: Any) -> SimpleGridReward:
    if isinstance(value, str) and value.upper() in SimpleGridReward.__members__:
        return SimpleGridReward[value.upper()]
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and 0 <= value <= 3:
        return SimpleGridReward(int(value))
    raise ValueError(f"reward_type must be 0-3, AND/NAND/OR/XOR or a SimpleGridReward; got {value!r}")


class SimpleGridNode(NamedTuple):
    X: int
    Y: int


class SimpleGridFamily(Family):
    name = "SimpleGrid"
    n_actions = 5
    node_fields = ("X", "Y")
    reward_parameters = RewardParameters(
        means=("optimal_mean_reward", "sub_optimal_mean_reward"),
        distributions=("optimal_distribution", "sub_optimal_distribution", "other_distribution"),
    )
    optimal_mean_reward: float
    sub_optimal_mean_reward: float

    def __init__(self, *, size: int, reward_type: Any, n_starting_states: int, rewards: RewardArguments) -> None:
        self.size = integer_parameter("size", size, 2, self.name)
        self.check_memory()
        self.reward_type = _reward_type(reward_type)
        # The starting cells are drawn among the (size-1)^2 cells closest to the centre.
        self.n_starting_states = integer_parameter(
            "n_starting_states", n_starting_states, 1, self.name, (self.size - 1) ** 2
        )
        self.set_rewards(rewards)

    def default_rewards(self, stochastic: bool, v: float) -> tuple[Distribution, ...]:
        """Optimal, sub-optimal and other: point masses 1, 0 and 0.5, or Betas of means ``mu_o``, ``mu_s / 10`` and
        ``mu_s`` (``mu_o = optimal_mean_reward``, ``mu_s = sub_optimal_mean_reward``)."""
        if not stochastic:
            # [paper≠code] the paper calls the per-step reward small; the reference pays 0.5 deterministically.
            return PointMass(1.0), PointMass(0.0), PointMass(0.5)
        # The Betas need both means in (0, 1).
        mu_o, mu_s = self.optimal_mean_reward, self.sub_optimal_mean_reward
        check_default_reward_parameter("optimal_mean_reward", mu_o, 1)
        check_default_reward_parameter("sub_optimal_mean_reward", mu_s, 1)
        return beta_with_mean(v, mu_o), beta_with_mean(v, mu_s, 10), beta_with_mean(v, mu_s)

    def max_states(self) -> int:
        """The ``size^2`` cells."""
        return self.size**2

    def size_parameters(self) -> dict[str, Any]:
        return {"size": self.size}

    def outcomes(self, node: SimpleGridNode, action: int) -> list[tuple[SimpleGridNode, float]]:
        x, y, top = node.X, node.Y, self.size - 1
        if action == UP:
            nxt = SimpleGridNode(x, min(y + 1, top))
        elif action == RIGHT:
            nxt = SimpleGridNode(min(x + 1, top), y)
        elif action == DOWN:
            nxt = SimpleGridNode(x, max(y - 1, 0))
        elif action == LEFT:
            nxt = SimpleGridNode(max(x - 1, 0), y)
        else:
            nxt = node
        return [(nxt, 1.0)]

    def _is_corner(self, x: int, y: int) -> bool:
        return x in (0, self.size - 1) and y in (0, self.size - 1)

    def reward(self, node: SimpleGridNode, action: int, next_node: SimpleGridNode) -> Distribution:
        if next_node == node and self._is_corner(node.X, node.Y):
            good = self.reward_type.is_good(node.X, node.Y)
            return self.dists["optimal_distribution" if good else "sub_optimal_distribution"]
        return self.dists["other_distribution"]

    def candidate_starts(self, G: np.random.RandomState) -> list[SimpleGridNode]:
        """The ``(size-1)^2`` possible starting cells: by squared distance to the centre, the closest tie group
        shuffled with ``G.shuffle``, later tie groups in row-major ``(X, then Y)`` order."""
        c = (self.size - 1) / 2
        cells = [(x, y) for x in range(self.size) for y in range(self.size)]  # row-major, as np.where lists them
        dist = {cell: (cell[0] - c) ** 2 + (cell[1] - c) ** 2 for cell in cells}
        levels = sorted(set(dist.values()))
        closest = [list(cell) for cell in cells if dist[cell] == levels[0]]
        G.shuffle(closest)  # a Python list, as in the reference: one bounded draw per position
        order = [tuple(cell) for cell in closest]
        order += [cell for level in levels[1:] for cell in cells if dist[cell] == level]
        return [SimpleGridNode(*cell) for cell in order[: (self.size - 1) ** 2]]

    def starting_nodes(self, G: np.random.RandomState, F: random.Random):
        possible = self.candidate_starts(G)
        starts = possible[: self.n_starting_states]
        G.shuffle(starts)
        if len(starts) > 1:
            F.randint(0, 10_000)  # the reference seeds its starting-state sampler from F (nothing structural)
        return starts, [1.0 / len(starts)] * len(starts), possible

    def params(self) -> tuple[tuple[str, Any], ...]:
        return (
            ("size", self.size),
            ("reward_type", self.reward_type.name),
            ("n_starting_states", self.n_starting_states),
            ("optimal_mean_reward", self.optimal_mean_reward),
            ("sub_optimal_mean_reward", self.sub_optimal_mean_reward),
            *self.distribution_params(),
        )

    def layout(self) -> tuple[tuple[str, Any], ...]:
        return (("size", self.size), ("reward_type", self.reward_type.name))


def render_simple_grid(info: MDPInfo, node: tuple[int, ...]) -> list[list[str]]:
    """``size x size`` grid: corners ``+`` (optimal loop) / ``-`` (sub-optimal loop) per ``reward_type``, ``A`` at the
    agent; printed row ``r`` is ``Y = size-1-r``, column ``c`` is ``X`` (symbols ``[" ", "A", "+", "-"]``)."""
    size = info.layout_value("size")
    reward_type = SimpleGridReward[info.layout_value("reward_type")]
    grid = [[" "] * size for _ in range(size)]
    for x in (0, size - 1):
        for y in (0, size - 1):
            grid[size - 1 - y][x] = "+" if reward_type.is_good(x, y) else "-"
    x, y = node
    grid[size - 1 - y][x] = "A"
    return grid


register_renderer(SimpleGridFamily.name, render_simple_grid)


@family_builder(SimpleGridFamily)
def simple_grid(
    *,
    episodic: bool,
    seed: int,
    size: int,
    reward_type: Any = SimpleGridReward.XOR,
    n_starting_states: int = 1,
    p_rand: float | None = None,
    p_lazy: float | None = None,
    randomize_actions: bool = True,
    make_reward_stochastic: bool = False,
    reward_variance_multiplier: float = 1.0,
    optimal_mean_reward: float = 0.9,
    sub_optimal_mean_reward: float = 0.2,
    optimal_distribution: Any = None,
    sub_optimal_distribution: Any = None,
    other_distribution: Any = None,
    H: int | None = None,
) -> MDP:
    """Build a SimpleGrid MDP (docs/families.md §2.3).

    ``S = size^2``. Starting cells: ``n_starting_states`` of the ``(size-1)^2`` cells closest to the centre (seeded
    shuffles), uniform. Default rewards: deterministic optimal 1, sub-optimal 0, other 0.5 ([paper≠code]: the paper
    calls the step reward small); stochastic (``v = reward_variance_multiplier``, ``mu_o = optimal_mean_reward``,
    ``mu_s = sub_optimal_mean_reward``) optimal ``Beta(v, v (1/mu_o - 1))``, sub-optimal ``Beta(v, v (10/mu_s - 1))``,
    other ``Beta(v, v (1/mu_s - 1))``. Default episodic horizon ``1 +`` the largest eccentricity of the possible
    starting cells (3 -> 4, 4 -> 6, 5 -> 8, ..., 20 -> 36).

    Raises:
      ValueError: ``size < 2``; ``reward_type`` not in 0-3 / AND, NAND, OR, XOR; ``n_starting_states`` outside
        ``[1, (size-1)^2]``; ``optimal_mean_reward - 0.1 <= sub_optimal_mean_reward``; stochastic default rewards
        with a mean outside (0, 1); distributions not given all-or-none or not matching ``make_reward_stochastic``.
    """
