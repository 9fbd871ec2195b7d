"""RiverSwim (Strehl & Littman 2008; paper App. C; docs/families.md §2.1).

A chain ``X = 0 .. size-1`` starting at ``X = 0``; LEFT (0) moves to ``max(X-1, 0)``, RIGHT (1) to
``min(X+1, size-1)``, deterministically (the classic "current" is replaced by ``p_rand`` / ``p_lazy``). RIGHT at the
right end pays the optimal reward, LEFT at the left end a small sub-optimal one, everything else the "other" reward.
"""

from __future__ import annotations

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

__all__ = ["RiverSwimNode", "RiverSwimFamily", "river_swim"]

LEFT, RIGHT = 0, 1


class RiverSwimNode(NamedTuple):
    X: int


class RiverSwimFamily(Family):
    name = "RiverSwim"
    n_actions = 2
    node_fields = ("X",)
    reward_parameters = RewardParameters(
        means=("optimal_mean_reward", "sub_optimal_mean_reward"),
        distributions=("optimal_distribution", "sub_optimal_distribution", "other_distribution"),
    )
    optimal_mean_reward: float
    sub_optimal_mean_reward: float

    def __init__(self, *, size: int, episodic: bool, rewards: RewardArguments) -> None:
        self.size = integer_parameter("size", size, 2, self.name)
        self.check_memory()
        self.episodic = episodic
        self.set_rewards(rewards)

    def default_rewards(self, stochastic: bool, v: float) -> tuple[Distribution, ...]:
        """Optimal, sub-optimal and other: point masses 1, 0.005 and 0, or Betas of means ``mu_o``, ``mu_s`` and ``mu_s
        / 10`` (``mu_s = sub_optimal_mean_reward / size`` when episodic)."""
        if not stochastic:
            return PointMass(1.0), PointMass(0.005), PointMass(0.0)
        # With sub_optimal_mean_reward < optimal_mean_reward - 0.1 the Betas are proper exactly when both means lie in
        # (0, 1).
        check_default_reward_parameter("optimal_mean_reward", self.optimal_mean_reward, 1)
        check_default_reward_parameter("sub_optimal_mean_reward", self.sub_optimal_mean_reward, 1)
        mu_s = self.sub_optimal_mean_reward / (self.size if self.episodic else 1)
        mu_o = self.optimal_mean_reward
        return beta_with_mean(v, mu_o), beta_with_mean(v, mu_s), beta_with_mean(v, mu_s, 10)

    def outcomes(self, node: RiverSwimNode, action: int) -> list[tuple[RiverSwimNode, float]]:
        x = node.X
        return [(RiverSwimNode(min(x + 1, self.size - 1) if action == RIGHT else max(x - 1, 0)), 1.0)]

    def reward(self, node: RiverSwimNode, action: int, next_node: RiverSwimNode) -> Distribution:
        if node.X == self.size - 1 and action == RIGHT:
            return self.dists["optimal_distribution"]
        if node.X == 0 and action == LEFT:
            return self.dists["sub_optimal_distribution"]
        return self.dists["other_distribution"]

    def max_states(self) -> int:
        """``size`` cells."""
        return self.size

    def size_parameters(self) -> dict[str, Any]:
        return {"size": self.size}

    def starting_nodes(self, G: np.random.RandomState, F: random.Random):
        start = RiverSwimNode(0)
        return [start], [1.0], [start]

    def params(self) -> tuple[tuple[str, Any], ...]:
        return (
            ("size", self.size),
            ("optimal_mean_reward", self.optimal_mean_reward),
            ("sub_optimal_mean_reward", self.sub_optimal_mean_reward),
            *self.distribution_params(),
        )

    def layout(self) -> tuple[tuple[str, Any], ...]:
        return (("size", self.size),)


def render_river_swim(info: MDPInfo, node: tuple[int, ...]) -> list[list[str]]:
    """One row: ``S`` at the start, ``G`` at the end, ``A`` at the agent (symbols ``[" ", "A", "S", "G"]``)."""
    size = info.layout_value("size")
    row = [" "] * size
    row[0], row[-1] = "S", "G"
    row[node[0]] = "A"
    return [row]


register_renderer(RiverSwimFamily.name, render_river_swim)


@family_builder(RiverSwimFamily)
def river_swim(
    *,
    episodic: bool,
    seed: int,
    size: int,
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
    """Build a RiverSwim MDP (docs/families.md §2.1). Default horizon ``H = size``.

    Default rewards: deterministic optimal 1, sub-optimal 0.005, other 0; stochastic (``v =
    reward_variance_multiplier``, ``mu_o = optimal_mean_reward``, ``mu_s = sub_optimal_mean_reward``, divided by
    ``size`` when episodic) optimal ``Beta(v, v (1/mu_o - 1))``, sub-optimal ``Beta(v, v (1/mu_s - 1))``, other
    ``Beta(v, v (10/mu_s - 1))``.

    Raises:
      ValueError: ``size < 2``; ``optimal_mean_reward - 0.1 <= sub_optimal_mean_reward``; stochastic default rewards
        with ``optimal_mean_reward`` or ``sub_optimal_mean_reward`` outside ``(0, 1)``; distributions not given
        all-or-none or not matching ``make_reward_stochastic``.
    """
