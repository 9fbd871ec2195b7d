"""DeepSea (Osband et al. 2019; paper App. C; docs/families.md §2.2).

A ``size x size`` triangle explored by diving: the agent starts at the top-left ``(X=0, Y=size-1)`` and every step
goes one row down (``Y-1``) and one column LEFT (0, ``max(X-1, 0)``) or RIGHT (1, ``min(X+1, size-1)``); from the
bottom row ``Y = 0`` every action jumps back to the start. LEFT pays a small sub-optimal reward everywhere (the
bottom row included), RIGHT pays the "other" reward, except RIGHT at the bottom-right corner ``(size-1, 0)``, which
pays the optimal reward. The episodic version has the fixed horizon ``H = size``; ``p_lazy`` is not allowed.
"""

from __future__ import annotations

import random
from typing import Any, NamedTuple

import numpy as np

from jaxmdp.mdp import MDP, MDPInfo
from jaxmdp.mdp_families.construction import Family, family_builder, integer_parameter
from jaxmdp.mdp_families.distributions import (
    Beta,
    Distribution,
    PointMass,
    RewardArguments,
    RewardParameters,
    beta_with_mean,
    check_default_reward_parameter,
)
from jaxmdp.render import register_renderer

__all__ = ["DeepSeaNode", "DeepSeaFamily", "deep_sea"]

LEFT, RIGHT = 0, 1


class DeepSeaNode(NamedTuple):
    X: int
    Y: int


class DeepSeaFamily(Family):
    name = "DeepSea"
    n_actions = 2
    node_fields = ("X", "Y")
    lazy_allowed = False
    reward_parameters = RewardParameters(
        means=("optimal_return", "suboptimal_return"),
        distributions=("optimal_distribution", "sub_optimal_distribution", "other_distribution"),
    )
    optimal_return: float
    suboptimal_return: float

    def __init__(self, *, size: int, rewards: RewardArguments) -> None:
        self.size = integer_parameter("size", size, 2, self.name)
        self.check_memory()
        self.set_rewards(rewards)

    def default_rewards(self, stochastic: bool, v: float) -> tuple[Distribution, ...]:
        """Optimal, sub-optimal and other: point masses 1, ``1/size^2`` (whatever ``suboptimal_return`` is, as in
        the reference) and 0, or Betas of means ``1 - r_opt/size``, ``r_sub/size`` and ``1/(1 + 10(size/r_sub -
        1))``."""
        if not stochastic:
            return PointMass(1.0), PointMass(1.0 / self.size**2), PointMass(0.0)
        # The Beta parameters are positive only for returns in (0, size).
        check_default_reward_parameter("suboptimal_return", self.suboptimal_return, self.size, f"size={self.size}")
        check_default_reward_parameter("optimal_return", self.optimal_return, self.size, f"size={self.size}")
        return (
            Beta(v * (self.size / self.optimal_return - 1), v),
            beta_with_mean(v, self.suboptimal_return, self.size),
            Beta(v, 10 * v * (self.size / self.suboptimal_return - 1)),
        )

    def outcomes(self, node: DeepSeaNode, action: int) -> list[tuple[DeepSeaNode, float]]:
        if node.Y == 0:
            return [(DeepSeaNode(0, self.size - 1), 1.0)]
        x = min(node.X + 1, self.size - 1) if action == RIGHT else max(node.X - 1, 0)
        return [(DeepSeaNode(x, node.Y - 1), 1.0)]

    def reward(self, node: DeepSeaNode, action: int, next_node: DeepSeaNode) -> Distribution:
        if action == RIGHT and node.X == self.size - 1 and node.Y == 0:
            return self.dists["optimal_distribution"]
        if action == LEFT:
            return self.dists["sub_optimal_distribution"]
        return self.dists["other_distribution"]

    def starting_nodes(self, G: np.random.RandomState, F: random.Random):
        start = DeepSeaNode(0, self.size - 1)
        return [start], [1.0], [start]

    def fixed_horizon(self) -> int:
        return self.size

    def max_states(self) -> int:
        """The ``size (size + 1) / 2`` cells of the triangle."""
        return self.size * (self.size + 1) // 2

    def size_parameters(self) -> dict[str, Any]:
        return {"size": self.size}

    def params(self) -> tuple[tuple[str, Any], ...]:
        return (
            ("size", self.size),
            ("optimal_return", self.optimal_return),
            ("suboptimal_return", self.suboptimal_return),
            *self.distribution_params(),
        )

    def layout(self) -> tuple[tuple[str, Any], ...]:
        return (("size", self.size),)


def render_deep_sea(info: MDPInfo, node: tuple[int, ...]) -> list[list[str]]:
    """``size x size`` blanks with ``A`` at the agent; printed row ``r`` is ``Y = size-1-r``, column ``c`` is ``X``
    (symbols ``["A", " "]``)."""
    size = info.layout_value("size")
    x, y = node
    grid = [[" "] * size for _ in range(size)]
    grid[size - 1 - y][x] = "A"
    return grid


register_renderer(DeepSeaFamily.name, render_deep_sea)


@family_builder(DeepSeaFamily)
def deep_sea(
    *,
    episodic: bool,
    seed: int,
    size: int,
    p_rand: float | None = None,
    p_lazy: float | None = None,
    randomize_actions: bool = True,
    make_reward_stochastic: bool = False,
    reward_variance_multiplier: float = 1.0,
    optimal_return: float = 1.0,
    suboptimal_return: float = 0.5,
    optimal_distribution: Any = None,
    sub_optimal_distribution: Any = None,
    other_distribution: Any = None,
    H: int | None = None,
) -> MDP:
    """Build a DeepSea MDP (docs/families.md §2.2).

    ``S = size (size + 1) / 2`` reachable cells. Default rewards: deterministic optimal 1, sub-optimal ``1/size^2``,
    other 0; stochastic (``v = reward_variance_multiplier``) optimal ``Beta(v (size/optimal_return - 1), v)``,
    sub-optimal ``Beta(v, v (size/suboptimal_return - 1))``, other ``Beta(v, 10 v (size/suboptimal_return - 1))``.

    Raises:
      ValueError: ``size < 2``; ``p_lazy`` given (DeepSea has no lazy mechanic; ``None`` or 0 only);
        ``suboptimal_return >= optimal_return - 0.1``; ``H`` given (the episodic horizon is fixed to ``size``).
    """
