"""The hyperparameter-search MDP samplers of the reference (paper App. F; benchmark.md §7), every family, both settings.

``sample_parameters(family, n, episodic, seed)`` draws ``n`` constructor parameter sets from one
``numpy.random.RandomState(seed)`` (a private generator, seeded as the reference seeds its own): for each sample the
draws of the family's row below happen in the listed order (``u``: one ``random()``; ``Dir(a)``: one ``dirichlet(a)``;
``choice``/``randint``: one call of that name), then ``p_rand`` and ``p_lazy`` below 0.01 become ``None`` and every
float, the reward distributions' parameters included, is rounded to 4 decimals. ``v`` is the reward variance
multiplier ``2u + 0.005``; ``b(q) = 1/q - 1`` (``b(0.9) = 1/9``, ``b(0.2) = 4``, ``b(0.02) = 49``).

=============  ==========================================================================================
RiverSwim      ``(p_rand, p_lazy, .) = 0.9 Dir(.2, .2, 5)``; size episodic ``int(min(2.5 + 200/(45u + 11), 25))``,
               continuous ``int((6u + 2)^2.2)``; stochastic ``choice([T, F])``; ``v``.
               Beta: sub ``(v, v b(.2))``, opt ``(v, v b(.9))``, other ``(v, v b(.02))``; point masses .005, 1, 0
DeepSea        size ``int((1 + min(800/(100u + 35), 25)) (0.8 if episodic else 1))``; ``p_rand = min(2/(8u + 3), .95)``;
               stochastic; ``v``. Beta: sub ``(v, v(2 size - 1))``, opt ``(v(size - 1), v)``, other
               ``(v, 10 v (2 size - 1))``; point masses ``1/size^2``, 1, 0
SimpleGrid     ``0.9 Dir``; size ``int(1 + min(800/(100u + 35), 25) (0.8 if episodic else 1))``;
               ``n_starting_states = randint(1, 5)``; stochastic; ``v``; ``reward_type = randint(4)``.
               Beta: sub ``(v, v b(.02))``, opt ``(v, v b(.9))``, other ``(v, v b(.2))``; point masses 0, 1, .5
FrozenLake     ``0.9 Dir``; size episodic ``choice([5, 6], p=[.665, .335])``, continuous
               ``int(2.5 + min(400/(150u + 35), 15))``; ``p_frozen = min((.55u + .45)^.3, .95)``; stochastic; ``v``.
               Beta: default ``(v, v (size^2/0.1 - 1))``, goal ``(v(size^2 - 1), v)``; point masses 0, 1
MiniGridEmpty  ``0.9 Dir``; size episodic ``int(min(5 + 14/(8u + 1), 20))``, continuous
               ``int(1.5 min(5 + 14/(8u + 1), 20))``; ``n_starting_states = randint(1, 5)``; stochastic; ``v``.
               Beta: opt ``(v, v(size^2 - 1))``, other ``(v(size^2 - 1), v)`` (swapped with respect to the family's
               defaults, as the reference: such MDPs pay little at the goal); point masses 1, 0
MiniGridRooms  ``0.9 Dir``; ``(x, y, .) = Dir(.2, .2, 1)``; ``n_rooms = min(9, int(2x + 2)^2)``;
               ``room_size = min(9, int(7y + 3))``, episodic ``max(room_size - 3, 3)``; ``n_starting_states``;
               stochastic; ``v``; distributions as MiniGridEmpty with ``size = int(room_size sqrt(n_rooms))``
Taxi           ``(p_rand, p_lazy, .) = 0.5 Dir(.2, .2, 5)``, both times 0.8 if episodic; size episodic 5,
               continuous ``choice([5, 6, 7], p=[.525, .325, .15])``; stochastic; ``v``.
               Beta: default ``(v, v b(.2))``, success ``(v, v b(.9))``, failure ``(v, v b(.02))``; point masses
               0.1, 1, 0
=============  ==========================================================================================

The samplers never set ``randomize_actions``, so sampled MDPs permute their actions (the family default), and Taxi
keeps its default layout (``length=2``, 4 locations).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from hardness.benchmark.instance import Instance
from jaxmdp.mdp_families import Beta, PointMass

__all__ = ["FAMILIES", "SAMPLERS", "sample_parameters", "sample_instances"]

#: The families with a sampler, in the reference's order (App. F; MG-DoorKey is excluded there).
FAMILIES = ("RiverSwim", "DeepSea", "FrozenLake", "SimpleGrid", "MiniGridEmpty", "MiniGridRooms", "Taxi")

Draw = dict[str, Any]


def _b(q: float) -> float:
    """``1/q - 1``: the second Beta parameter per unit ``v`` of a reward with mean ``q``."""
    return 1.0 / q - 1.0


def _lazy_rand(rng: np.random.RandomState, scale: float) -> tuple[float, float]:
    p_rand, p_lazy, _ = scale * rng.dirichlet([0.2, 0.2, 5])
    return p_rand, p_lazy


def _stochastic_and_v(rng: np.random.RandomState) -> tuple[bool, float]:
    stochastic = bool(rng.choice([True, False]))
    return stochastic, 2 * rng.random() + 0.005


def _rewards(stochastic: bool, betas: dict[str, tuple[float, float]], points: dict[str, float]) -> Draw:
    if stochastic:
        return {k: ("beta", ab) for k, ab in betas.items()}
    return {k: ("deterministic", (c,)) for k, c in points.items()}


def _river_swim(rng: np.random.RandomState, episodic: bool) -> Draw:
    p_rand, p_lazy = _lazy_rand(rng, 0.9)
    u = rng.random()
    size = int(min(2.5 + 200 / (45 * u + 11), 25)) if episodic else int((6 * u + 2) ** 2.2)
    stochastic, v = _stochastic_and_v(rng)
    betas = dict(sub_optimal_distribution=(v, v * _b(0.2)), optimal_distribution=(v, v * _b(0.9)),
                 other_distribution=(v, v * _b(0.02)))
    points = dict(sub_optimal_distribution=0.005, optimal_distribution=1.0, other_distribution=0.0)
    return dict(size=size, p_rand=p_rand, p_lazy=p_lazy, make_reward_stochastic=stochastic,
                reward_variance_multiplier=v, **_rewards(stochastic, betas, points))


def _deep_sea(rng: np.random.RandomState, episodic: bool) -> Draw:
    size = int((1 + min(800 / (100 * rng.random() + 35), 25)) * (0.8 if episodic else 1.0))
    p_rand = min(2 / (8 * rng.random() + 3), 0.95)
    stochastic, v = _stochastic_and_v(rng)
    betas = dict(sub_optimal_distribution=(v, v * (2 * size - 1)), optimal_distribution=(v * (size - 1), v),
                 other_distribution=(v, 10 * v * (2 * size - 1)))
    points = dict(sub_optimal_distribution=1 / size**2, optimal_distribution=1.0, other_distribution=0.0)
    return dict(size=size, p_rand=p_rand, make_reward_stochastic=stochastic, reward_variance_multiplier=v,
                **_rewards(stochastic, betas, points))


def _simple_grid(rng: np.random.RandomState, episodic: bool) -> Draw:
    p_rand, p_lazy = _lazy_rand(rng, 0.9)
    size = int(1 + min(800 / (100 * rng.random() + 35), 25) * (0.8 if episodic else 1.0))
    n_starting_states = int(rng.randint(1, 5))
    stochastic, v = _stochastic_and_v(rng)
    reward_type = int(rng.randint(4))
    betas = dict(sub_optimal_distribution=(v, v * _b(0.02)), optimal_distribution=(v, v * _b(0.9)),
                 other_distribution=(v, v * _b(0.2)))
    points = dict(sub_optimal_distribution=0.0, optimal_distribution=1.0, other_distribution=0.5)
    return dict(size=size, reward_type=reward_type, n_starting_states=n_starting_states, p_rand=p_rand,
                p_lazy=p_lazy, make_reward_stochastic=stochastic, reward_variance_multiplier=v,
                **_rewards(stochastic, betas, points))


def _frozen_lake(rng: np.random.RandomState, episodic: bool) -> Draw:
    p_rand, p_lazy = _lazy_rand(rng, 0.9)
    if episodic:
        size = int(rng.choice([5, 6], p=[0.665, 0.335]))
    else:
        size = int(2.5 + min(400 / (150 * rng.random() + 35), 15))
    p_frozen = min((0.55 * rng.random() + 0.45) ** 0.3, 0.95)
    stochastic, v = _stochastic_and_v(rng)
    betas = dict(goal_r=(v * (size**2 - 1), v), default_r=(v, v * (size**2 / 0.1 - 1)))
    points = dict(goal_r=1.0, default_r=0.0)
    return dict(size=size, p_frozen=p_frozen, p_rand=p_rand, p_lazy=p_lazy, make_reward_stochastic=stochastic,
                reward_variance_multiplier=v, **_rewards(stochastic, betas, points))


def _minigrid_rewards(stochastic: bool, v: float, size: int) -> Draw:
    # The reference's sampler swaps the family's default Beta parameters (benchmark.md §7 [quirk]): kept.
    betas = dict(optimal_distribution=(v, v * (size**2 - 1)), other_distribution=(v * (size**2 - 1), v))
    return _rewards(stochastic, betas, dict(optimal_distribution=1.0, other_distribution=0.0))


def _minigrid_empty(rng: np.random.RandomState, episodic: bool) -> Draw:
    p_rand, p_lazy = _lazy_rand(rng, 0.9)
    raw = min(5 + 14 / (8 * rng.random() + 1), 20)
    size = int(raw) if episodic else int(1.5 * raw)
    n_starting_states = int(rng.randint(1, 5))
    stochastic, v = _stochastic_and_v(rng)
    return dict(size=size, n_starting_states=n_starting_states, p_rand=p_rand, p_lazy=p_lazy,
                make_reward_stochastic=stochastic, reward_variance_multiplier=v,
                **_minigrid_rewards(stochastic, v, size))


def _minigrid_rooms(rng: np.random.RandomState, episodic: bool) -> Draw:
    p_rand, p_lazy = _lazy_rand(rng, 0.9)
    x, y, _ = rng.dirichlet([0.2, 0.2, 1])
    n_rooms = min(9, int(2 * x + 2) ** 2)
    room_size = min(9, int(7 * y + 3))
    if episodic:
        room_size = max(room_size - 3, 3)
    n_starting_states = int(rng.randint(1, 5))
    stochastic, v = _stochastic_and_v(rng)
    size = int(room_size * math.sqrt(n_rooms))  # used by the distributions only: not a constructor parameter
    return dict(room_size=room_size, n_rooms=n_rooms, n_starting_states=n_starting_states, p_rand=p_rand,
                p_lazy=p_lazy, make_reward_stochastic=stochastic, reward_variance_multiplier=v,
                **_minigrid_rewards(stochastic, v, size))


def _taxi(rng: np.random.RandomState, episodic: bool) -> Draw:
    p_rand, p_lazy = _lazy_rand(rng, 0.5)
    if episodic:
        p_rand, p_lazy, size = 0.8 * p_rand, 0.8 * p_lazy, 5
    else:
        size = int(rng.choice([5, 6, 7], p=[0.525, 0.325, 0.15]))
    stochastic, v = _stochastic_and_v(rng)
    betas = dict(default_r=(v, v * _b(0.2)), successfully_delivery_r=(v, v * _b(0.9)),
                 failure_delivery_r=(v, v * _b(0.02)))
    points = dict(default_r=0.1, successfully_delivery_r=1.0, failure_delivery_r=0.0)
    return dict(size=size, p_rand=p_rand, p_lazy=p_lazy, make_reward_stochastic=stochastic,
                reward_variance_multiplier=v, **_rewards(stochastic, betas, points))


#: Family -> one sample's draws ``(rng, episodic) -> parameters`` (before the ``None`` rule and the rounding).
SAMPLERS: dict[str, Callable[[np.random.RandomState, bool], Draw]] = {
    "RiverSwim": _river_swim,
    "DeepSea": _deep_sea,
    "FrozenLake": _frozen_lake,
    "SimpleGrid": _simple_grid,
    "MiniGridEmpty": _minigrid_empty,
    "MiniGridRooms": _minigrid_rooms,
    "Taxi": _taxi,
}


def _round(x: Any) -> Any:
    """Every float of a nested structure rounded to 4 decimals (integers and booleans unchanged)."""
    if isinstance(x, bool) or x is None or isinstance(x, (int, np.integer, str)):
        return x
    if isinstance(x, (float, np.floating)):
        return round(float(x), 4)
    if isinstance(x, tuple):
        return tuple(_round(y) for y in x)
    raise TypeError(f"unexpected sampled value {x!r}")


def _finish(draw: Draw) -> dict[str, Any]:
    """The ``None`` rule on the unrounded probabilities, the rounding, and distributions as objects."""
    out = {}
    for k, x in draw.items():
        if k in ("p_rand", "p_lazy") and x < 0.01:
            out[k] = None
            continue
        x = _round(x)
        if isinstance(x, tuple):
            kind, args = x
            x = Beta(*args) if kind == "beta" else PointMass(*args)
        out[k] = x
    return out


def sample_parameters(family: str, n: int, episodic: bool, seed: int = 42) -> list[dict[str, Any]]:
    """``n`` constructor parameter sets of ``family`` for the setting, drawn from ``RandomState(seed)`` (module
    docstring; the reference's ``sample_mdp_parameters``)."""
    if family not in SAMPLERS:
        raise ValueError(f"family must be one of {FAMILIES}; got {family!r}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer; got {n!r}")
    rng = np.random.RandomState(seed)
    return [_finish(SAMPLERS[family](rng, bool(episodic))) for _ in range(int(n))]


def sample_instances(
    episodic: bool,
    n_per_family: int,
    *,
    seed: int = 42,
    families: Sequence[str] = FAMILIES,
    set_name: str | None = None,
) -> list[Instance]:
    """``n_per_family`` sampled MDPs of every family (each family's sampler seeded with ``seed``, as the reference
    does), labelled ``Family/sample_i``."""
    set_name = set_name or ("search episodic" if episodic else "search continuous")
    out = []
    for family in families:
        for i, params in enumerate(sample_parameters(family, n_per_family, episodic, seed)):
            out.append(Instance(set_name, f"{family}/sample_{i}", family, bool(episodic), tuple(params.items())))
    return out
