"""The Colosseum benchmark as data: the 80 MDPs of docs/benchmark.md §3 (4 settings x 20), and their construction.

Each :class:`BenchmarkEntry` holds the keys its gin file sets (verbatim; everything else is the family default),
the effective reward distributions the reference prints, and what the reference reports for seed 0 (``S``, ``H``,
communication class, cached diameter and value norm). :func:`build` makes the MDP for a seed through
:func:`jaxmdp.make` (the same integer seeds the MDP and the agent in the reference's protocol).

Reward distributions: several gin files set distributions other than the family defaults (every Taxi entry, the
episodic RiverSwim entries -- whose "optimal" end pays ``Beta(0.01, 0.11)``, mean 0.083, less per step than the left
end, see the remark below docs/benchmark.md's tables -- and some continuous MiniGridEmpty entries). Wherever a
stochastic entry's printed effective distributions differ from the family defaults at the printed two-decimal precision,
they are passed explicitly (:attr:`BenchmarkEntry.overrides`) with the printed parameters taken literally. This
reproduces the cached seed-0 diameters and value norms (checked in the tests); the print cannot tell ``0.11`` from
``1/0.9 - 1``, which give the same cached numbers.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import jaxmdp
from jaxmdp.mdp_families import Beta

__all__ = ["SETTINGS", "BenchmarkEntry", "BENCHMARK", "entries", "build", "build_suite"]

#: The four benchmark settings, in the paper's order.
SETTINGS = ("episodic ergodic", "episodic communicating", "continuous ergodic", "continuous communicating")


@dataclasses.dataclass(frozen=True)
class BenchmarkEntry:
    """One benchmark MDP (docs/benchmark.md §3). ``H``, ``n_states``, the class and the cached measures are the
    reference's values for seed 0 (``None`` where not applicable or not cached)."""

    setting: str
    family: str
    scope: str
    gin_params: tuple[tuple[str, Any], ...]
    effective_distributions: str
    n_states: int
    H: int | None
    communication_class: str
    cached_diameter: float | None
    cached_value_norm: float | None

    @property
    def overrides(self) -> tuple[tuple[str, Any], ...]:
        """Explicit reward distributions where the printed ones differ from the family defaults (module docstring),
        worked out on first use: it builds the MDP, so importing the suite does not."""
        return _distribution_overrides(self.family, self.gin_params, self.effective_distributions)

    @property
    def episodic(self) -> bool:
        return self.setting.startswith("episodic")

    @property
    def name(self) -> str:
        return f"{self.setting}/{self.family}/{self.scope}"

    def kwargs(self) -> dict[str, Any]:
        """Constructor keyword arguments: the gin keys, then the explicit overrides."""
        return {**dict(self.gin_params), **dict(self.overrides)}


#: Printed labels of each family's reward distributions (docs/benchmark.md §3) -> constructor parameter names.
_DISTRIBUTION_PARAMS: dict[str, dict[str, str]] = {
    **{
        fam: {"opt": "optimal_distribution", "sub": "sub_optimal_distribution", "other": "other_distribution"}
        for fam in ("RiverSwim", "DeepSea", "SimpleGrid")
    },
    **{fam: {"opt": "optimal_distribution", "other": "other_distribution"} for fam in ("MiniGridEmpty", "MiniGridRooms")},
    "FrozenLake": {"goal": "goal_r", "default": "default_r"},
    "Taxi": {"default": "default_r", "success": "successfully_delivery_r", "failure": "failure_delivery_r"},
}


def _parse_betas(printed: str) -> dict[str, tuple[float, float]]:
    """``"opt=Beta(1.0,0.11), other=Beta(1.0,4.0)"`` -> ``{"opt": (1.0, 0.11), ...}`` (Beta entries only)."""
    out = {}
    for item in printed.replace(" ", "").split("),"):
        label, _, dist = item.partition("=")
        if dist.startswith("Beta("):
            a, b = dist[len("Beta(") :].rstrip(")").split(",")
            out[label] = (float(a), float(b))
    return out


@functools.cache
def _distribution_overrides(
    family: str, gin_params: tuple[tuple[str, Any], ...], printed: str
) -> tuple[tuple[str, Any], ...]:
    """Explicit distributions when the printed ones differ from the family defaults (see the module docstring)."""
    params = dict(gin_params)
    printed_betas = _parse_betas(printed)
    if not params.get("make_reward_stochastic") or not printed_betas:
        return ()
    names = _DISTRIBUTION_PARAMS[family]
    defaults = dict(jaxmdp.make(family, episodic=False, seed=0, **params).info.params)
    for label, (a, b) in printed_betas.items():
        default = defaults[names[label]]  # e.g. "Beta(1, 0.111111)"
        da, db = (float(x) for x in default[len("Beta(") : -1].split(","))
        if (round(da, 2), round(db, 2)) != (round(a, 2), round(b, 2)):
            return tuple((names[lab], Beta(a2, b2)) for lab, (a2, b2) in printed_betas.items())
    return ()


def _entry(setting, family, scope, params, dists, S, H, cls, D, VN) -> BenchmarkEntry:
    return BenchmarkEntry(
        setting=setting,
        family=family,
        scope=scope,
        gin_params=tuple(params.items()),
        effective_distributions=dists,
        n_states=S,
        H=H,
        communication_class=cls,
        cached_diameter=D,
        cached_value_norm=VN,
    )


# fmt: off
BENCHMARK: tuple[BenchmarkEntry, ...] = (
    # episodic ergodic
    _entry("episodic ergodic", "DeepSea", "prms_0", dict(size=10, p_rand=0.4, make_reward_stochastic=False, randomize_actions=False), "opt=Deterministic(1.0), sub=Deterministic(0.01), other=Deterministic(0.0)", 55, 10, "ERGODIC", 74.4995, 0.8787),
    _entry("episodic ergodic", "DeepSea", "prms_1", dict(size=13, p_rand=0.3, make_reward_stochastic=True, randomize_actions=False), "opt=Beta(12.0,1.0), sub=Beta(1.0,25.0), other=Beta(1.0,250.0)", 91, 13, "ERGODIC", 91.3881, 0.8163),
    _entry("episodic ergodic", "FrozenLake", "prms_0", dict(size=4, make_reward_stochastic=True, randomize_actions=True, p_lazy=0.03, p_frozen=0.98, p_rand=0.001), "goal=Beta(15.0,1.0), default=Beta(1.0,159.0)", 16, 7, "ERGODIC", 84.5498, 0.4378),
    _entry("episodic ergodic", "MiniGridEmpty", "prms_0", dict(size=10, make_reward_stochastic=False, randomize_actions=False, p_lazy=None, p_rand=0.05, n_starting_states=3), "opt=Deterministic(1.0), other=Deterministic(0.0)", 400, 23, "ERGODIC", 22.1188, 2.5800),
    _entry("episodic ergodic", "MiniGridEmpty", "prms_1", dict(size=10, make_reward_stochastic=True, randomize_actions=False, p_lazy=None, p_rand=0.3, n_starting_states=3), "opt=Beta(99.0,1.0), other=Beta(1.0,99.0)", 400, 23, "ERGODIC", 64.3434, 2.6450),
    _entry("episodic ergodic", "MiniGridEmpty", "prms_2", dict(size=10, make_reward_stochastic=False, randomize_actions=False, p_lazy=0.05, p_rand=0.2, n_starting_states=3), "opt=Deterministic(1.0), other=Deterministic(0.0)", 400, 23, "ERGODIC", 45.1697, 2.6974),
    _entry("episodic ergodic", "MiniGridEmpty", "prms_3", dict(size=8, make_reward_stochastic=False, randomize_actions=False, p_lazy=None, p_rand=0.3, n_starting_states=3), "opt=Deterministic(1.0), other=Deterministic(0.0)", 256, 19, "ERGODIC", 46.4045, 1.9378),
    _entry("episodic ergodic", "MiniGridEmpty", "prms_4", dict(size=8, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.02, p_rand=0.4, n_starting_states=3), "opt=Beta(63.0,1.0), other=Beta(1.0,63.0)", 256, 19, "ERGODIC", 83.5988, 1.8044),
    _entry("episodic ergodic", "MiniGridEmpty", "prms_5", dict(size=6, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.1, p_rand=0.05, n_starting_states=3), "opt=Beta(35.0,1.0), other=Beta(1.0,35.0)", 144, 15, "ERGODIC", 16.6006, 1.6334),
    _entry("episodic ergodic", "MiniGridEmpty", "prms_6", dict(size=4, make_reward_stochastic=False, randomize_actions=False, p_lazy=0.1, p_rand=0.4, n_starting_states=3), "opt=Deterministic(1.0), other=Deterministic(0.0)", 64, 11, "ERGODIC", 67.5558, 1.4703),
    _entry("episodic ergodic", "MiniGridRooms", "prms_0", dict(randomize_actions=False, make_reward_stochastic=True, room_size=3, n_rooms=4, p_rand=0.001, p_lazy=None), "opt=Beta(35.0,1.0), other=Beta(1.0,35.0)", 160, 19, "ERGODIC", 16.0257, 3.2560),
    _entry("episodic ergodic", "MiniGridRooms", "prms_1", dict(randomize_actions=False, make_reward_stochastic=True, room_size=3, n_rooms=9, p_rand=0.1, p_lazy=0.01), "opt=Beta(80.0,1.0), other=Beta(1.0,80.0)", 372, 27, "ERGODIC", 46.9877, 2.9730),
    _entry("episodic ergodic", "MiniGridRooms", "prms_2", dict(randomize_actions=False, make_reward_stochastic=True, room_size=4, n_rooms=4, p_rand=0.1, p_lazy=0.01), "opt=Beta(63.0,1.0), other=Beta(1.0,63.0)", 272, 23, "ERGODIC", 36.2953, 3.0715),
    _entry("episodic ergodic", "RiverSwim", "prms_0", dict(make_reward_stochastic=True, randomize_actions=False, size=5, p_lazy=0.1, p_rand=0.01), "opt=Beta(0.01,0.11), sub=Beta(2.4,24.0), other=Beta(2.4,249.0)", 5, 5, "ERGODIC", 7.7749, 0.0806),
    _entry("episodic ergodic", "RiverSwim", "prms_1", dict(make_reward_stochastic=True, randomize_actions=False, size=30, p_lazy=0.01, p_rand=0.01), "opt=Beta(0.01,0.11), sub=Beta(14.9,149.0), other=Beta(14.9,1499.0)", 30, 30, "ERGODIC", 46.4330, 0.0810),
    _entry("episodic ergodic", "SimpleGrid", "prms_0", dict(reward_type=3, size=10, randomize_actions=False, make_reward_stochastic=True, p_lazy=0.2, p_rand=0.01), "opt=Beta(1.0,0.11), sub=Beta(1.0,49.0), other=Beta(1.0,4.0)", 100, 17, "ERGODIC", 14.0644, 1.0895),
    _entry("episodic ergodic", "SimpleGrid", "prms_1", dict(reward_type=3, size=16, randomize_actions=False, make_reward_stochastic=True, p_lazy=0.2, p_rand=0.2), "opt=Beta(1.0,0.11), sub=Beta(1.0,49.0), other=Beta(1.0,4.0)", 256, 28, "ERGODIC", 34.0390, 1.0711),
    _entry("episodic ergodic", "SimpleGrid", "prms_2", dict(reward_type=3, size=16, randomize_actions=False, make_reward_stochastic=False, p_lazy=0.01, p_rand=0.2), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.5)", 256, 28, "ERGODIC", 21.8695, 0.7047),
    _entry("episodic ergodic", "Taxi", "prms_0", dict(randomize_actions=False, make_reward_stochastic=True, p_lazy=0.001, size=4, length=1, width=1, space=1, n_locations=3, p_rand=0.01), "default=Beta(0.8,20.0), success=Beta(1.0,0.1), failure=Beta(0.8,50.0)", 108, 24, "ERGODIC", 61.8463, 0.7922),
    _entry("episodic ergodic", "Taxi", "prms_1", dict(randomize_actions=False, make_reward_stochastic=True, p_lazy=0.01, size=4, length=1, width=1, space=1, n_locations=3, p_rand=0.2), "default=Beta(0.8,6.0), success=Beta(1.0,0.1), failure=Beta(0.8,40.0)", 108, 24, "ERGODIC", 73.8003, 0.5721),
    # episodic communicating
    _entry("episodic communicating", "DeepSea", "prms_0", dict(size=5, p_rand=None, make_reward_stochastic=True, randomize_actions=False), "opt=Beta(4.0,1.0), sub=Beta(1.0,9.0), other=Beta(1.0,90.0)", 15, 5, "COMMUNICATING", 5.0000, 0.6348),
    _entry("episodic communicating", "DeepSea", "prms_1", dict(size=25, p_rand=None, make_reward_stochastic=True, randomize_actions=False), "opt=Beta(24.0,1.0), sub=Beta(1.0,49.0), other=Beta(1.0,490.0)", 325, 25, "COMMUNICATING", 25.0000, 0.9242),
    _entry("episodic communicating", "FrozenLake", "prms_0", dict(size=3, make_reward_stochastic=True, randomize_actions=False, p_lazy=None, p_frozen=0.9, p_rand=None), "goal=Beta(8.0,1.0), default=Beta(1.0,89.0)", 9, 5, "COMMUNICATING", 26.6625, 0.3334),
    _entry("episodic communicating", "MiniGridEmpty", "prms_0", dict(size=6, make_reward_stochastic=True, randomize_actions=False, p_lazy=None, p_rand=None, n_starting_states=3), "opt=Beta(35.0,1.0), other=Beta(1.0,35.0)", 144, 15, "COMMUNICATING", 11.6667, 1.6489),
    _entry("episodic communicating", "MiniGridEmpty", "prms_1", dict(size=6, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.35, p_rand=None, n_starting_states=5), "opt=Beta(35.0,1.0), other=Beta(1.0,35.0)", 144, 15, "COMMUNICATING", 52.6851, 1.7955),
    _entry("episodic communicating", "MiniGridEmpty", "prms_2", dict(size=6, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.25, p_rand=0.1, n_starting_states=3), "opt=Beta(35.0,1.0), other=Beta(1.0,35.0)", 144, 15, "ERGODIC", 33.5212, 1.6932),
    _entry("episodic communicating", "MiniGridEmpty", "prms_3", dict(size=10, make_reward_stochastic=False, randomize_actions=False, p_lazy=0.1, p_rand=None, n_starting_states=5), "opt=Deterministic(1.0), other=Deterministic(0.0)", 400, 23, "COMMUNICATING", 23.5998, 2.4986),
    _entry("episodic communicating", "MiniGridEmpty", "prms_4", dict(size=10, make_reward_stochastic=False, randomize_actions=False, p_lazy=0.15, p_rand=0.1, n_starting_states=3), "opt=Deterministic(1.0), other=Deterministic(0.0)", 400, 23, "ERGODIC", 42.7570, 2.6031),
    _entry("episodic communicating", "MiniGridRooms", "prms_0", dict(randomize_actions=False, make_reward_stochastic=True, room_size=4, n_rooms=4, p_rand=None, p_lazy=None), "opt=Beta(63.0,1.0), other=Beta(1.0,63.0)", 272, 23, "COMMUNICATING", 20.5000, 3.1607),
    _entry("episodic communicating", "MiniGridRooms", "prms_1", dict(randomize_actions=False, make_reward_stochastic=False, room_size=3, n_rooms=9, p_rand=None, p_lazy=0.05), "opt=Deterministic(1.0), other=Deterministic(0.0)", 372, 27, "COMMUNICATING", 26.1729, 3.3155),
    _entry("episodic communicating", "MiniGridRooms", "prms_2", dict(randomize_actions=False, make_reward_stochastic=False, room_size=3, n_rooms=9, p_rand=None, p_lazy=0.1), "opt=Deterministic(1.0), other=Deterministic(0.0)", 372, 27, "COMMUNICATING", 35.2007, 3.2408),
    _entry("episodic communicating", "MiniGridRooms", "prms_3", dict(randomize_actions=False, make_reward_stochastic=False, room_size=3, n_rooms=4, p_rand=None, p_lazy=0.15), "opt=Deterministic(1.0), other=Deterministic(0.0)", 160, 19, "COMMUNICATING", 25.1429, 3.0370),
    _entry("episodic communicating", "RiverSwim", "prms_0", dict(make_reward_stochastic=True, randomize_actions=False, size=25, p_lazy=0.05, p_rand=None), "opt=Beta(0.01,0.11), sub=Beta(12.4,124.0), other=Beta(12.4,1249.0)", 25, 25, "COMMUNICATING", 85.6177, 0.0809),
    _entry("episodic communicating", "RiverSwim", "prms_1", dict(make_reward_stochastic=False, randomize_actions=False, size=40, p_lazy=None, p_rand=None), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.0)", 40, 40, "COMMUNICATING", 40.0000, 0.0000),
    _entry("episodic communicating", "SimpleGrid", "prms_0", dict(size=10, randomize_actions=False, make_reward_stochastic=True, p_lazy=0.5), "opt=Beta(1.0,0.11), sub=Beta(1.0,49.0), other=Beta(1.0,4.0)", 100, 17, "COMMUNICATING", 73.4276, 1.2357),
    _entry("episodic communicating", "SimpleGrid", "prms_1", dict(size=13, randomize_actions=False, make_reward_stochastic=True, p_lazy=0.4), "opt=Beta(1.0,0.11), sub=Beta(1.0,49.0), other=Beta(1.0,4.0)", 169, 22, "COMMUNICATING", 28.8768, 1.2586),
    _entry("episodic communicating", "SimpleGrid", "prms_2", dict(size=13, randomize_actions=False, make_reward_stochastic=False, p_lazy=None), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.5)", 169, 22, "COMMUNICATING", 13.0000, 0.0000),
    _entry("episodic communicating", "SimpleGrid", "prms_3", dict(size=20, randomize_actions=False, make_reward_stochastic=True, p_lazy=0.4), "opt=Beta(1.0,0.11), sub=Beta(1.0,49.0), other=Beta(1.0,4.0)", 400, 36, "COMMUNICATING", 47.3147, 1.2342),
    _entry("episodic communicating", "Taxi", "prms_0", dict(randomize_actions=False, make_reward_stochastic=True, p_lazy=0.01, size=4, length=1, width=1, space=1, n_locations=3, p_rand=None), "default=Beta(0.7,30.0), success=Beta(0.4,0.1), failure=Beta(0.8,50.0)", 108, 24, "COMMUNICATING", 61.7097, 0.7068),
    _entry("episodic communicating", "Taxi", "prms_1", dict(randomize_actions=False, make_reward_stochastic=True, p_lazy=0.2, size=5, length=1, width=1, space=1, n_locations=3, p_rand=None), "default=Beta(0.7,30.0), success=Beta(0.4,0.1), failure=Beta(0.8,50.0)", 162, 37, "COMMUNICATING", 98.4511, 0.5822),
    # continuous ergodic
    _entry("continuous ergodic", "DeepSea", "prms_0", dict(size=20, p_rand=0.1, make_reward_stochastic=False, randomize_actions=False), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.0)", 210, None, "ERGODIC", 70.9627, 0.9579),
    _entry("continuous ergodic", "FrozenLake", "prms_0", dict(size=5, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.01, p_frozen=0.95, p_rand=0.05), "goal=Beta(24.0,1.0), default=Beta(1.0,249.0)", 23, None, "ERGODIC", 22.9163, 0.2880),
    _entry("continuous ergodic", "MiniGridEmpty", "prms_0", dict(size=12, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.05, p_rand=0.495, n_starting_states=3), "opt=Beta(143.0,1.0), other=Beta(1.0,143.0)", 576, None, "ERGODIC", 55.4838, 1.9078),
    _entry("continuous ergodic", "MiniGridEmpty", "prms_1", dict(size=12, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.1, p_rand=0.395, n_starting_states=3), "opt=Beta(143.0,1.0), other=Beta(1.0,143.0)", 576, None, "ERGODIC", 48.5555, 2.0168),
    _entry("continuous ergodic", "MiniGridEmpty", "prms_2", dict(size=10, make_reward_stochastic=False, randomize_actions=False, p_lazy=0.02, p_rand=0.7, n_starting_states=3), "opt=Deterministic(1.0), other=Deterministic(0.0)", 400, None, "ERGODIC", 79.2357, 1.4084),
    _entry("continuous ergodic", "MiniGridEmpty", "prms_3", dict(size=14, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.02, p_rand=0.6, n_starting_states=3), "opt=Beta(195.0,1.0), other=Beta(1.0,195.0)", 784, None, "ERGODIC", 79.6475, 1.6978),
    _entry("continuous ergodic", "MiniGridEmpty", "prms_4", dict(size=10, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.1, p_rand=0.21, n_starting_states=3), "opt=Beta(1.0,0.11), other=Beta(1.0,4.0)", 400, None, "ERGODIC", 31.0117, 1.4845),
    _entry("continuous ergodic", "MiniGridEmpty", "prms_5", dict(size=14, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.02, p_rand=0.4, n_starting_states=3), "opt=Beta(0.5,0.11), other=Beta(1.5,4.0)", 784, None, "ERGODIC", 52.0243, 1.1426),
    _entry("continuous ergodic", "MiniGridEmpty", "prms_6", dict(size=14, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.05, p_rand=0.31, n_starting_states=3), "opt=Beta(1.0,0.11), other=Beta(1.0,4.0)", 784, None, "ERGODIC", 46.3929, 1.4972),
    _entry("continuous ergodic", "MiniGridEmpty", "prms_7", dict(size=14, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.1, p_rand=0.6, n_starting_states=3), "opt=Beta(0.3,0.11), other=Beta(2.0,4.0)", 784, None, "ERGODIC", 86.7276, 0.6645),
    _entry("continuous ergodic", "MiniGridRooms", "prms_0", dict(randomize_actions=False, make_reward_stochastic=True, room_size=3, n_rooms=16, p_rand=0.1, p_lazy=0.4), "opt=Beta(143.0,1.0), other=Beta(1.0,143.0)", 672, None, "ERGODIC", 64.1765, 1.9748),
    _entry("continuous ergodic", "MiniGridRooms", "prms_1", dict(randomize_actions=False, make_reward_stochastic=False, room_size=5, n_rooms=9, p_rand=0.3, p_lazy=0.4), "opt=Deterministic(1.0), other=Deterministic(0.0)", 948, None, "ERGODIC", 98.7664, 1.8588),
    _entry("continuous ergodic", "RiverSwim", "prms_0", dict(make_reward_stochastic=False, randomize_actions=False, size=30, p_lazy=0.1, p_rand=0.2), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.0)", 30, None, "ERGODIC", 40.1037, 0.8967),
    _entry("continuous ergodic", "RiverSwim", "prms_1", dict(make_reward_stochastic=True, randomize_actions=False, size=50, p_lazy=0.1, p_rand=0.1), "opt=Beta(1.0,0.11), sub=Beta(1.0,4.0), other=Beta(1.0,49.0)", 50, None, "ERGODIC", 60.4250, 0.8304),
    _entry("continuous ergodic", "RiverSwim", "prms_2", dict(make_reward_stochastic=True, randomize_actions=False, size=80, p_lazy=0.001, p_rand=0.2), "opt=Beta(1.0,0.11), sub=Beta(1.0,4.0), other=Beta(1.0,49.0)", 80, None, "ERGODIC", 98.6923, 0.7810),
    _entry("continuous ergodic", "RiverSwim", "prms_3", dict(make_reward_stochastic=False, randomize_actions=False, size=80, p_lazy=0.1, p_rand=0.01), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.0)", 80, None, "ERGODIC", 88.6587, 0.9926),
    _entry("continuous ergodic", "SimpleGrid", "prms_0", dict(size=15, randomize_actions=False, make_reward_stochastic=True, p_lazy=0.4, p_rand=0.4), "opt=Beta(1.0,0.11), sub=Beta(1.0,49.0), other=Beta(1.0,4.0)", 225, None, "ERGODIC", 75.0722, 0.6344),
    _entry("continuous ergodic", "SimpleGrid", "prms_1", dict(size=10, randomize_actions=False, make_reward_stochastic=False, p_lazy=0.2, p_rand=0.01), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.5)", 100, None, "ERGODIC", 22.7043, 0.5297),
    _entry("continuous ergodic", "SimpleGrid", "prms_2", dict(size=20, randomize_actions=False, make_reward_stochastic=False, p_lazy=0.1, p_rand=0.1), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.5)", 400, None, "ERGODIC", 46.4996, 0.4764),
    _entry("continuous ergodic", "Taxi", "prms_0", dict(randomize_actions=False, make_reward_stochastic=True, p_lazy=0.01, size=4, length=1, width=1, space=1, n_locations=3, p_rand=0.1), "default=Beta(0.8,20.0), success=Beta(1.0,0.1), failure=Beta(0.8,50.0)", 108, None, "ERGODIC", 99.2759, 0.1971),
    # continuous communicating
    _entry("continuous communicating", "DeepSea", "prms_0", dict(size=40, p_rand=None, make_reward_stochastic=True, randomize_actions=False), "opt=Beta(39.0,1.0), sub=Beta(1.0,79.0), other=Beta(1.0,790.0)", 820, None, "COMMUNICATING", 78.0000, 0.9539),
    _entry("continuous communicating", "DeepSea", "prms_1", dict(size=40, p_rand=None, make_reward_stochastic=False, randomize_actions=False), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.0)", 820, None, "COMMUNICATING", 78.0000, 0.0000),
    _entry("continuous communicating", "DeepSea", "prms_2", dict(size=35, p_rand=None, make_reward_stochastic=True, randomize_actions=False), "opt=Beta(34.0,1.0), sub=Beta(1.0,69.0), other=Beta(1.0,690.0)", 630, None, "COMMUNICATING", 68.0000, 0.9468),
    _entry("continuous communicating", "FrozenLake", "prms_0", dict(size=4, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.01, p_frozen=0.95, p_rand=None), "goal=Beta(15.0,1.0), default=Beta(1.0,159.0)", 15, None, "COMMUNICATING", 20.7566, 0.2800),
    _entry("continuous communicating", "FrozenLake", "prms_1", dict(size=5, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.35, p_frozen=0.9, p_rand=None), "goal=Beta(24.0,1.0), default=Beta(1.0,249.0)", 22, None, "COMMUNICATING", 48.8585, 0.2519),
    _entry("continuous communicating", "MiniGridEmpty", "prms_0", dict(size=12, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.25, p_rand=None, n_starting_states=3), "opt=Beta(1.0,0.11), other=Beta(1.0,4.0)", 576, None, "COMMUNICATING", 34.6657, 1.3520),
    _entry("continuous communicating", "MiniGridEmpty", "prms_1", dict(size=12, make_reward_stochastic=False, randomize_actions=False, p_lazy=0.3, p_rand=None, n_starting_states=3), "opt=Deterministic(1.0), other=Deterministic(0.0)", 576, None, "COMMUNICATING", 37.1419, 1.9042),
    _entry("continuous communicating", "MiniGridEmpty", "prms_2", dict(size=8, make_reward_stochastic=False, randomize_actions=False, p_lazy=0.3, p_rand=None, n_starting_states=3), "opt=Deterministic(1.0), other=Deterministic(0.0)", 256, None, "COMMUNICATING", 25.7137, 1.4812),
    _entry("continuous communicating", "MiniGridEmpty", "prms_3", dict(size=8, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.7, p_rand=None, n_starting_states=3), "opt=Beta(1.0,0.11), other=Beta(1.0,4.0)", 256, None, "COMMUNICATING", 59.9960, 1.5419),
    _entry("continuous communicating", "MiniGridEmpty", "prms_4", dict(size=12, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.7, p_rand=None, n_starting_states=3), "opt=Beta(1.0,0.11), other=Beta(1.0,4.0)", 576, None, "COMMUNICATING", 86.6620, 1.5415),
    _entry("continuous communicating", "MiniGridRooms", "prms_0", dict(randomize_actions=False, make_reward_stochastic=True, room_size=5, n_rooms=9, p_rand=None, p_lazy=0.3), "opt=Beta(224.0,1.0), other=Beta(1.0,224.0)", 948, None, "COMMUNICATING", 54.2847, 2.2207),
    _entry("continuous communicating", "MiniGridRooms", "prms_1", dict(randomize_actions=False, make_reward_stochastic=True, room_size=3, n_rooms=9, p_rand=None, p_lazy=0.5), "opt=Beta(80.0,1.0), other=Beta(1.0,80.0)", 372, None, "COMMUNICATING", 51.9982, 2.0177),
    _entry("continuous communicating", "MiniGridRooms", "prms_2", dict(randomize_actions=False, make_reward_stochastic=True, room_size=5, n_rooms=9, p_rand=None, p_lazy=0.5), "opt=Beta(224.0,1.0), other=Beta(1.0,224.0)", 948, None, "COMMUNICATING", 75.9973, 1.8305),
    _entry("continuous communicating", "RiverSwim", "prms_0", dict(make_reward_stochastic=True, randomize_actions=False, size=25, p_lazy=0.1, p_rand=None), "opt=Beta(1.0,0.11), sub=Beta(1.0,4.0), other=Beta(1.0,49.0)", 25, None, "COMMUNICATING", 26.6666, 0.8781),
    _entry("continuous communicating", "RiverSwim", "prms_1", dict(make_reward_stochastic=True, randomize_actions=False, size=90, p_lazy=0.03, p_rand=None), "opt=Beta(1.0,0.11), sub=Beta(1.0,4.0), other=Beta(1.0,49.0)", 90, None, "COMMUNICATING", 91.7527, 0.8795),
    _entry("continuous communicating", "SimpleGrid", "prms_0", dict(size=15, randomize_actions=False, make_reward_stochastic=True, p_lazy=0.2, p_rand=None), "opt=Beta(2.0,0.11), sub=Beta(0.3,49.0), other=Beta(0.3,4.0)", 225, None, "COMMUNICATING", 34.9997, 0.8737),
    _entry("continuous communicating", "SimpleGrid", "prms_1", dict(size=16, randomize_actions=False, make_reward_stochastic=False, p_lazy=0.065, p_rand=None), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.5)", 256, None, "COMMUNICATING", 32.0854, 0.4993),
    _entry("continuous communicating", "SimpleGrid", "prms_2", dict(size=25, randomize_actions=False, make_reward_stochastic=True, p_lazy=0.1, p_rand=None), "opt=Beta(2.0,0.11), sub=Beta(0.3,49.0), other=Beta(0.3,4.0)", 625, None, "COMMUNICATING", 53.3327, 0.8762),
    _entry("continuous communicating", "SimpleGrid", "prms_3", dict(size=25, randomize_actions=False, make_reward_stochastic=False, p_lazy=0.3, p_rand=None), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.5)", 625, None, "COMMUNICATING", 68.5702, 0.4958),
    _entry("continuous communicating", "Taxi", "prms_0", dict(randomize_actions=False, make_reward_stochastic=True, p_lazy=0.01, size=4, length=1, width=1, space=1, n_locations=3, p_rand=None), "default=Beta(0.7,30.0), success=Beta(0.4,0.1), failure=Beta(0.8,50.0)", 108, None, "COMMUNICATING", 88.8435, 0.0810),
)
# fmt: on


def entries(setting: str | None = None, family: str | None = None) -> list[BenchmarkEntry]:
    """The benchmark entries, optionally of one setting and/or family."""
    if setting is not None and setting not in SETTINGS:
        raise ValueError(f"setting must be one of {SETTINGS}; got {setting!r}")
    return [e for e in BENCHMARK if (setting is None or e.setting == setting) and (family is None or e.family == family)]


def build(entry: BenchmarkEntry, seed: int = 0) -> jaxmdp.MDP:
    """The MDP of ``entry`` for ``seed`` (raises ``ValueError`` if its family is not registered)."""
    return jaxmdp.make(entry.family, episodic=entry.episodic, seed=seed, **entry.kwargs())


def build_suite(
    seed: int = 0, setting: str | None = None, *, skip_missing: bool = False
) -> list[tuple[BenchmarkEntry, jaxmdp.MDP]]:
    """``(entry, mdp)`` for every entry (of ``setting``); with ``skip_missing`` the entries whose family is not
    registered are left out instead of raising."""
    out = []
    for e in entries(setting):
        if skip_missing and e.family not in jaxmdp.families():
            continue
        out.append((e, build(e, seed)))
    return out
