"""Taxi (Dietterich 2000; paper App. C; docs/families.md §2.7).

**Walls.** ``size`` rows ``X = 0..size-1`` of ``size`` columns ``Y`` are built top to bottom: for ``j = 0, 1, ...`` a
wall pattern row is made (even ``j``: ``floor((width + space) / 2)`` free cells first; then units ``i = 0, 1, ...``
of ``width`` wall cells when ``i mod (space + 1) = 0``, else one free cell, cut at ``size`` entries), appended
``length`` times, then followed by one free row, until there are ``size`` rows. E.g. ``size = 5`` with the defaults
gives ``01010 / 01010 / 00000 / 10101 / 10101`` (1 = wall).

**Locations.** ``q = ceil(sqrt(n_locations))^2`` quadrants: the rows and the columns are cut into ``sqrt(q)`` nearly
equal blocks (``numpy.array_split``), quadrant ``i`` is the ``i``-th (row block, column block) pair in row-major
order restricted to the free cells (row-major). The draw ``G.randint(len(quadrant))`` for every quadrant in order is
repeated until all picked cells are pairwise farther apart (Euclidean) than ``max(size / sqrt(q) / 2, 2)``; the picks
are then shuffled with ``G.shuffle`` and the first ``n_locations`` are the locations.

**Nodes** ``(X, Y, XPass, YPass, XDest, YDest)``, the passenger at ``(-1, -1)`` when on board. **Actions** 0
MoveSouth (``Y - 1``), 1 MoveNorth (``Y + 1``), 2 MoveEast (``X + 1``), 3 MoveWest (``X - 1``), 4 PickUpPassenger,
5 DropOffPassenger. A move enters the adjacent cell when it is free; picking up succeeds on the waiting passenger's
cell; dropping off the passenger on board at the destination draws a new task uniformly among the pairs (passenger
location ``p`` != taxi cell, destination ``d`` != ``p``) in location order; every other action leaves the node.
**Rewards** (chosen action and actual next node, so also for ``p_rand``/``p_lazy`` outcomes): a pick-up pays the
*failure* distribution unless the passenger was waiting before and is on board after (then *default*); a drop-off
pays *failure* unless the passenger was on board before and is not after (then *success*); moves pay *default*.

**Start**: every node with the passenger on a location, the destination on another location and the taxi on any free
cell, listed passenger location x destination x free cell and shuffled with ``G.shuffle``; uniform.

The horizon is ``floor(1.5 size^2)`` (or a larger requested ``H``), whatever the graph. Action randomisation is always
off, as in the reference (``randomize_actions`` is accepted and ignored; the parameter dictionary reports False).
Departures from the reference, where it would crash or hang: a quadrant without free cells raises ``ValueError``,
and so does a location draw that is rejected :data:`MAX_LOCATION_DRAWS` times in a row. Validation is also a little
stricter: ``width >= 1`` (the reference accepts 0 and builds the walls of 1), ``length, space >= 0`` (negative values
are meaningless or crash there), and partial reward distributions raise (the reference then ignores them).
"""

from __future__ import annotations

import itertools
import math
import random
from collections.abc import Callable
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

__all__ = ["TaxiNode", "TaxiFamily", "taxi", "taxi_walls", "MAX_LOCATION_DRAWS"]

MOVE_SOUTH, MOVE_NORTH, MOVE_EAST, MOVE_WEST, PICK_UP, DROP_OFF = range(6)
_MOVES = {MOVE_SOUTH: (0, -1), MOVE_NORTH: (0, 1), MOVE_EAST: (1, 0), MOVE_WEST: (-1, 0)}

#: Rejected location draws after which the layout is declared unable to hold well-separated locations.
MAX_LOCATION_DRAWS = 100_000


class TaxiNode(NamedTuple):
    X: int
    Y: int
    XPass: int
    YPass: int
    XDest: int
    YDest: int


def taxi_walls(size: int, length: int, width: int, space: int) -> np.ndarray:
    """Boolean ``[size, size]`` wall map indexed ``[X, Y]`` (see the module docstring)."""
    rows: list[list[int]] = []
    j = 0
    while len(rows) < size:
        row = _pattern_row(size, width, space, j)
        for _ in range(length):
            if len(rows) == size:
                break
            rows.append(row)
        if len(rows) < size:
            rows.append([0] * size)
        j += 1
    return np.array(rows, dtype=bool)


def _pattern_row(size: int, width: int, space: int, j: int) -> list[int]:
    row = [0] * ((width + space) // 2) if j % 2 == 0 else []
    i = 0
    while len(row) < size:
        row.extend([1] * width if i % (space + 1) == 0 else [0])
        i += 1
    return row[:size]


def taxi_free_cells(size: int, length: int, width: int, space: int) -> int:
    """The number of free cells of :func:`taxi_walls` (``size^2`` minus its sum), counted in closed form: a pattern
    row is its free prefix, then periods of ``width`` walls and ``space`` free cells, cut at ``size``; block ``j``
    is ``length`` copies of pattern row ``j`` and one free row, the last block cut at ``size`` rows."""

    def free_in_pattern(j: int) -> int:
        prefix = (width + space) // 2 if j % 2 == 0 else 0
        if prefix >= size:
            return size
        periods, rest = divmod(size - prefix, width + space)
        return prefix + periods * space + max(0, rest - width)

    blocks, rest = divmod(size, length + 1)
    even, odd = (blocks + 1) // 2, blocks // 2
    return (
        blocks * size
        + length * (even * free_in_pattern(0) + odd * free_in_pattern(1))
        + rest * free_in_pattern(blocks)
    )


class TaxiFamily(Family):
    name = "Taxi"
    n_actions = 6
    node_fields = ("X", "Y", "XPass", "YPass", "XDest", "YDest")
    randomize_actions_allowed = False
    reward_parameters = RewardParameters(
        means=("optimal_mean_reward", "sub_optimal_mean_reward"),
        distributions=("default_r", "successfully_delivery_r", "failure_delivery_r"),
    )
    optimal_mean_reward: float
    sub_optimal_mean_reward: float

    def __init__(
        self,
        *,
        size: int,
        episodic: bool,
        length: int,
        width: int,
        space: int,
        n_locations: int,
        rewards: RewardArguments,
    ) -> None:
        self.size = integer_parameter("size", size, 4, self.name)
        self.length = integer_parameter("length", length, 0, self.name, self.size - 1)
        self.width = integer_parameter("width", width, 1, self.name, self.size - 1)
        # The reference asks size > space / 2.
        self.space = integer_parameter("space", space, 0, self.name, 2 * self.size - 1)
        min_loc = 2 if episodic else 3
        self.n_locations = integer_parameter("n_locations", n_locations, min_loc, self.name)
        if not self.size > 2 * math.sqrt(self.n_locations):
            raise ValueError(
                f"n_locations must satisfy size > 2 sqrt(n_locations), i.e. n_locations < size^2 / 4 = "
                f"{self.size**2 / 4:g}, for {self.name}; got n_locations={n_locations}, size={self.size}"
            )
        self.check_memory()
        root = math.isqrt(self.n_locations)
        self.rows_of_quadrants = root if root * root == self.n_locations else root + 1
        self.n_quadrants = self.rows_of_quadrants**2
        self.set_rewards(rewards)
        fail, default, success = (
            self.dists[k].mean for k in ("failure_delivery_r", "default_r", "successfully_delivery_r")
        )
        if not fail < default < success:
            raise ValueError(
                "the reward means must satisfy failure_delivery_r < default_r < successfully_delivery_r; "
                f"got {fail:g}, {default:g}, {success:g}"
            )
        self.walls = taxi_walls(self.size, self.length, self.width, self.space)
        self.free = [(int(x), int(y)) for x, y in zip(*np.nonzero(~self.walls))]
        self.free_set = frozenset(self.free)
        blocks = np.array_split(np.arange(self.size), self.rows_of_quadrants)
        self.quadrants = [
            [(x, y) for x, y in self.free if x in set(bx.tolist()) and y in set(by.tolist())]
            for bx, by in itertools.product(blocks, blocks)
        ]
        for i, quadrant in enumerate(self.quadrants):
            if not quadrant:
                raise ValueError(
                    f"quadrant {i} of the {self.size}x{self.size} Taxi grid has no free cell; change size, length, "
                    f"width, space or n_locations (got {self.length}, {self.width}, {self.space}, {self.n_locations})"
                )
        self.locations: list[tuple[int, int]] = []

    def default_rewards(self, stochastic: bool, v: float) -> tuple[Distribution, ...]:
        """Default, successful and failed delivery: point masses 0.1, 1 and 0, or Betas of means ``mu_s``, ``mu_o``
        and ``mu_s / 10`` (``mu_o = optimal_mean_reward``, ``mu_s = sub_optimal_mean_reward``)."""
        if not stochastic:
            return PointMass(0.1), PointMass(1.0), PointMass(0.0)
        # With the means' order checked the Betas are proper exactly when both lie in (0, 1).
        mu_s, mu_o = self.sub_optimal_mean_reward, self.optimal_mean_reward
        check_default_reward_parameter("sub_optimal_mean_reward", mu_s, 1)
        check_default_reward_parameter("optimal_mean_reward", mu_o, 1)
        return beta_with_mean(v, mu_s), beta_with_mean(v, mu_o), beta_with_mean(v, mu_s, 10)

    def max_states(self) -> int:
        """The free cells (:func:`taxi_free_cells`), times the passenger's ``n_locations`` places or the taxi, times
        the ``n_locations`` destinations (a waiting passenger's destination differs from its place)."""
        n = self.n_locations
        return taxi_free_cells(self.size, self.length, self.width, self.space) * (n * (n - 1) + n)

    def size_parameters(self) -> dict[str, Any]:
        return {"size": self.size, "n_locations": self.n_locations}

    def _draw_locations(self, G: np.random.RandomState) -> list[tuple[int, int]]:
        min_distance = max(self.size / self.rows_of_quadrants / 2, 2)
        for _ in range(MAX_LOCATION_DRAWS):
            picks = [quadrant[G.randint(len(quadrant))] for quadrant in self.quadrants]
            if all(math.dist(a, b) > min_distance for a, b in itertools.combinations(picks, 2)):
                G.shuffle(picks)
                return picks[: self.n_locations]
        raise ValueError(
            f"no set of Taxi locations pairwise farther apart than {min_distance:g} was drawn in {MAX_LOCATION_DRAWS} "
            f"tries; increase size or reduce n_locations (size={self.size}, n_locations={self.n_locations})"
        )

    def outcomes(self, node: TaxiNode, action: int) -> list[tuple[TaxiNode, float]]:
        x, y, xp, yp, xd, yd = node
        if action == DROP_OFF and xp == -1 and (x, y) == (xd, yd):
            tasks = [(p, d) for p in self.locations if p != (x, y) for d in self.locations if d != p]
            return [(TaxiNode(x, y, *p, *d), 1.0 / len(tasks)) for p, d in tasks]
        if action == PICK_UP and xp != -1 and (x, y) == (xp, yp):
            return [(TaxiNode(x, y, -1, -1, xd, yd), 1.0)]
        if action in _MOVES:
            dx, dy = _MOVES[action]
            if (x + dx, y + dy) in self.free_set:
                return [(TaxiNode(x + dx, y + dy, xp, yp, xd, yd), 1.0)]
        return [(node, 1.0)]

    def reward(self, node: TaxiNode, action: int, next_node: TaxiNode) -> Distribution:
        on_board_before, on_board_after = node.XPass == -1, next_node.XPass == -1
        if action == PICK_UP and (on_board_before or not on_board_after):
            return self.dists["failure_delivery_r"]
        if action == DROP_OFF:
            delivered = on_board_before and not on_board_after
            return self.dists["successfully_delivery_r" if delivered else "failure_delivery_r"]
        return self.dists["default_r"]

    def starting_nodes(self, G: np.random.RandomState, F: random.Random):
        self.locations = self._draw_locations(G)
        starts = [
            TaxiNode(*c, *p, *d)
            for p, d, c in itertools.product(self.locations, self.locations, self.free)
            if p != d
        ]
        G.shuffle(starts)
        F.randint(0, 10000)  # the reference's starting-sampler seed; keeps F in step
        return starts, [1.0 / len(starts)] * len(starts), starts

    def minimum_horizon(self, eccentricity: Callable[[], int]) -> int:
        """``floor(1.5 size^2)`` whatever the graph (docs/families.md §1.8); the eccentricity search is skipped."""
        return int(1.5 * self.size**2)

    def params(self) -> tuple[tuple[str, Any], ...]:
        return (
            ("size", self.size),
            ("length", self.length),
            ("width", self.width),
            ("space", self.space),
            # The reference reports the rounded-up number of quadrants here.
            ("n_locations", self.n_quadrants),
            ("optimal_mean_reward", self.optimal_mean_reward),
            ("sub_optimal_mean_reward", self.sub_optimal_mean_reward),
            *self.distribution_params(),
        )

    def layout(self) -> tuple[tuple[str, Any], ...]:
        walls = tuple(tuple(bool(w) for w in row) for row in self.walls)
        return (("size", self.size), ("walls", walls), ("locations", tuple(self.locations)))


def render_taxi(info: MDPInfo, node: tuple[int, ...]) -> list[list[str]]:
    """``X`` on walls, blanks elsewhere, then ``D`` at the destination, ``P`` at the waiting passenger and ``A`` at the
    taxi, indexed ``[X, Y]`` with the rows reversed (top printed row ``X = size-1``). Symbols
    ``[" ", "A", "X", "D", "P"]``. [paper≠code] the paper draws walls as ``W``; we keep the reference's ``X``."""
    walls = info.layout_value("walls")
    grid = [["X" if w else " " for w in row] for row in walls]
    x, y, xp, yp, xd, yd = node
    grid[xd][yd] = "D"
    if xp != -1:
        grid[xp][yp] = "P"
    grid[x][y] = "A"
    return grid[::-1]


register_renderer(TaxiFamily.name, render_taxi)


@family_builder(TaxiFamily)
def taxi(
    *,
    episodic: bool,
    seed: int,
    size: int,
    length: int = 2,
    width: int = 1,
    space: int = 1,
    n_locations: int = 4,
    optimal_mean_reward: float = 0.9,
    sub_optimal_mean_reward: float = 0.2,
    default_r: Any = None,
    successfully_delivery_r: Any = None,
    failure_delivery_r: Any = None,
    p_rand: float | None = None,
    p_lazy: float | None = None,
    randomize_actions: bool = True,
    make_reward_stochastic: bool = False,
    reward_variance_multiplier: float = 1.0,
    H: int | None = None,
) -> MDP:
    """Build a Taxi MDP (docs/families.md §2.7): ``S = free cells x n_locations^2``, horizon ``floor(1.5 size^2)``.

    Args:
      size: grid side, an integer ``>= 4``.
      length, width, space: wall pattern (``0 <= length < size``, ``1 <= width < size``, ``0 <= space < 2 size``).
      n_locations: number of pick-up/drop-off locations, ``>= 3`` (continuous) or ``>= 2`` (episodic), with
        ``size > 2 sqrt(n_locations)``.
      optimal_mean_reward, sub_optimal_mean_reward: means of the stochastic defaults (``opt - 0.1 > sub``, both in
        ``(0, 1)`` when the stochastic defaults are used):
        default ``Beta(v, v (1/sub - 1))``, success ``Beta(v, v (1/opt - 1))``, failure ``Beta(v, v (10/sub - 1))``;
        deterministic defaults 0.1, 1.0, 0.0.
      default_r, successfully_delivery_r, failure_delivery_r: reward distributions (all or none) with means
        ``failure < default < success``.
      randomize_actions: ignored: Taxi never relabels its actions (the reference forces it off).
      The other arguments are the common ones (:class:`~jaxmdp.mdp_families.construction.CommonParams`).
    """
