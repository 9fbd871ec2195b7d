"""Named sets of benchmark MDPs (benchmark.md §1-3, §7), each MDP a recipe that builds one instance per seed.

Sets, by name (:func:`instances`; one MDP of a set by its label, :func:`instance`; spaces, underscores and hyphens
are interchangeable in set names):

* the four settings of the paper's benchmark (§3.3, Table 2): ``"episodic ergodic"``, ``"episodic communicating"``,
  ``"continuous ergodic"``, ``"continuous communicating"`` (20 MDPs each, :mod:`hardness.benchmark.suite`);
* the reference's smoke-test sets ``"episodic quick test"`` and ``"continuous quick test"`` (7 MDPs each, one per
  family);
* the hyperparameter-search sets ``"search episodic"`` and ``"search continuous"``: ``n_per_family`` parameter sets
  drawn from every family's sampler (:mod:`hardness.benchmark.samplers`, App. F).

Per-seed semantics (the reference's protocol, benchmark.md §2): the same integer seed builds the MDP
(:meth:`Instance.build`) and seeds the agent (``jax.random.key(seed)``), so a seed-dependent family (every family
but RiverSwim and DeepSea, and any family with ``randomize_actions``) gives each seed its own MDP.
"""

from __future__ import annotations

from jaxmdp._checks import did_you_mean
from hardness.benchmark import samplers
from hardness.benchmark import suite as benchmark_suite
from hardness.benchmark.instance import Instance
from hardness.benchmark.suite import BenchmarkEntry, _entry

__all__ = [
    "SETTINGS",
    "QUICK_SETS",
    "SEARCH_SETS",
    "SET_NAMES",
    "QUICK_TEST",
    "Instance",
    "canonical_name",
    "is_episodic",
    "instances",
    "instance",
]

#: The paper's four benchmark settings, in its order.
SETTINGS: tuple[str, ...] = benchmark_suite.SETTINGS
#: The reference's quick-test sets (benchmark.md §3, "quick test").
QUICK_SETS: tuple[str, ...] = ("episodic quick test", "continuous quick test")
#: The hyperparameter-search sets (benchmark.md §7).
SEARCH_SETS: tuple[str, ...] = ("search episodic", "search continuous")
SET_NAMES: tuple[str, ...] = SETTINGS + QUICK_SETS + SEARCH_SETS


def _from_entry(set_name: str, e: BenchmarkEntry) -> Instance:
    return Instance(set_name, f"{e.family}/{e.scope}", e.family, e.episodic, tuple(e.kwargs().items()), e)


def _quick(setting, family, params, dists, S, H, cls, D=None, VN=None) -> BenchmarkEntry:
    return _entry(setting, family, "prms_0", params, dists, S, H, cls, D, VN)


_EQ, _CQ = QUICK_SETS
_TAXI = dict(size=4, length=1, width=1, space=1, n_locations=3)
_MG_BETA = "opt=Beta(35.0,1.0), other=Beta(1.0,35.0)"
_TAXI_BETA = "default=Beta(0.8,20.0), success=Beta(1.0,0.1), failure=Beta(0.8,50.0)"
_SG_BETA = "opt=Beta(1.0,0.11), sub=Beta(1.0,49.0), other=Beta(1.0,4.0)"

# fmt: off
#: The quick-test MDPs (benchmark.md §3): the keys their gin files set, the printed distributions and the reference's
#: seed-0 ``S``, ``H`` and class (and cached measures where the reference has them).
QUICK_TEST: tuple[BenchmarkEntry, ...] = (
    _quick(_EQ, "DeepSea", dict(size=10, p_rand=0.05, make_reward_stochastic=False, randomize_actions=False), "opt=Deterministic(1.0), sub=Deterministic(0.01), other=Deterministic(0.0)", 55, 10, "ERGODIC"),
    _quick(_EQ, "FrozenLake", dict(size=4, make_reward_stochastic=True, randomize_actions=True, p_lazy=0.03, p_frozen=0.90, p_rand=0.001), "goal=Beta(15.0,1.0), default=Beta(1.0,159.0)", 13, 7, "ERGODIC"),
    _quick(_EQ, "MiniGridEmpty", dict(size=7, make_reward_stochastic=False, randomize_actions=False, p_lazy=0.05, p_rand=0.05, n_starting_states=3), "opt=Deterministic(1.0), other=Deterministic(0.0)", 196, 17, "ERGODIC"),
    _quick(_EQ, "MiniGridRooms", dict(randomize_actions=False, make_reward_stochastic=True, room_size=3, n_rooms=4, p_rand=0.001, p_lazy=None), _MG_BETA, 160, 19, "ERGODIC", 16.0257, 3.2560),
    _quick(_EQ, "RiverSwim", dict(make_reward_stochastic=True, randomize_actions=False, size=5, p_lazy=0.1), "opt=Beta(0.01,0.11), sub=Beta(2.4,24.0), other=Beta(2.4,249.0)", 5, 5, "COMMUNICATING"),
    _quick(_EQ, "SimpleGrid", dict(reward_type=3, size=10, randomize_actions=False, make_reward_stochastic=True, p_lazy=0.2), _SG_BETA, 100, 17, "COMMUNICATING"),
    _quick(_EQ, "Taxi", dict(randomize_actions=False, make_reward_stochastic=True, p_lazy=0.001, **_TAXI, p_rand=0.01), _TAXI_BETA, 108, 24, "ERGODIC", 61.8463, 0.7922),
    _quick(_CQ, "DeepSea", dict(size=10, p_rand=0.1, make_reward_stochastic=False, randomize_actions=False), "opt=Deterministic(1.0), sub=Deterministic(0.01), other=Deterministic(0.0)", 55, None, "ERGODIC"),
    _quick(_CQ, "FrozenLake", dict(size=5, make_reward_stochastic=True, randomize_actions=False, p_lazy=0.01, p_frozen=0.8, p_rand=0.05), "goal=Beta(24.0,1.0), default=Beta(1.0,249.0)", 19, None, "ERGODIC"),
    _quick(_CQ, "MiniGridEmpty", dict(size=6, make_reward_stochastic=True, p_lazy=0.05, p_rand=0.05, n_starting_states=3), _MG_BETA, 144, None, "ERGODIC"),
    _quick(_CQ, "MiniGridRooms", dict(make_reward_stochastic=True, room_size=3, n_rooms=4, p_rand=0.1), _MG_BETA, 160, None, "ERGODIC"),
    _quick(_CQ, "RiverSwim", dict(make_reward_stochastic=False, size=15, p_lazy=0.1, p_rand=0.2), "opt=Deterministic(1.0), sub=Deterministic(0.0), other=Deterministic(0.0)", 15, None, "ERGODIC"),
    _quick(_CQ, "SimpleGrid", dict(size=8, make_reward_stochastic=True, p_lazy=0.15), _SG_BETA, 64, None, "COMMUNICATING"),
    _quick(_CQ, "Taxi", dict(make_reward_stochastic=True, p_lazy=0.01, **_TAXI, p_rand=0.1), _TAXI_BETA, 108, None, "ERGODIC", 99.2759, 0.1971),
)
# fmt: on


def canonical_name(name: str) -> str:
    """``name`` with ``_``/``-`` read as spaces, checked against :data:`SET_NAMES` (``ValueError`` with the closest
    names otherwise)."""
    key = " ".join(str(name).replace("_", " ").replace("-", " ").lower().split())
    if key not in SET_NAMES:
        raise ValueError(f"unknown benchmark set {name!r}{did_you_mean(key, SET_NAMES, 0.5)} "
                         f"Known sets: {', '.join(SET_NAMES)}")
    return key


def is_episodic(name: str) -> bool:
    """Whether the set ``name`` holds episodic MDPs."""
    key = canonical_name(name)
    return key.startswith("episodic") or key == "search episodic"


def instances(name: str, *, n_per_family: int = 5, search_seed: int = 42) -> list[Instance]:
    """The MDPs of the set ``name`` (module docstring), in the reference's order.

    ``n_per_family`` and ``search_seed`` apply to the search sets only: that many parameter sets per family, drawn
    by :func:`hardness.benchmark.samplers.sample_instances` with ``RandomState(search_seed)`` (the reference's
    defaults: 5 and 42).
    """
    key = canonical_name(name)
    if key in SETTINGS:
        return [_from_entry(key, e) for e in benchmark_suite.entries(key)]
    if key in QUICK_SETS:
        return [_from_entry(key, e) for e in QUICK_TEST if e.setting == key]
    return samplers.sample_instances(key == "search episodic", n_per_family, seed=search_seed, set_name=key)


def instance(name: str, label: str, **kwargs: int) -> Instance:
    """The MDP ``label`` (e.g. ``"RiverSwim/prms_0"``) of the set ``name``; ``kwargs`` as for :func:`instances`.

    Raises:
      ValueError: naming ``label``, the closest labels of the set and all of them, when it is not one of its MDPs.
    """
    found = {inst.label: inst for inst in instances(name, **kwargs)}
    if label not in found:
        raise ValueError(f"label {label!r} is not an MDP of the set {canonical_name(name)!r}"
                         f"{did_you_mean(label, found, 0.5)} Its labels: "
                         f"{', '.join(found)}")
    return found[label]

