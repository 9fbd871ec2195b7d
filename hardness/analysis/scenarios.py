"""The four scenarios of the empirical hardness analysis (paper §3.2 and App. D), batched over values and seeds.

For one family, in the episodic or the continuous setting, every scenario computes the three measures of paper §2.2
(diameter, environmental value norm, sum of the reciprocals of the sub-optimality gaps; :func:`hardness.measures`)
for every ``(seed, value)`` of a grid, and their min-max normalisation of paper App. E:

1. ``p_rand``, the probability that a uniformly random action is executed instead of the chosen one;
2. ``p_lazy``, the probability that the MDP stays where it is instead of executing the chosen action;
3. the size of the MDP (the family's size parameter; the figures use the number of states);
4. the size of the MDP with ``p_rand = 0.1`` (:data:`SCENARIO_4_P_RAND`).

How the grid is computed (one jitted program per grid):

* scenarios 1-2, ``variant="paper"``: one base MDP per seed (built without the swept noise), the seeds stacked with
  :func:`jaxmdp.stack` (padded to common shapes when they differ, e.g. FrozenLake), and
  ``vmap(seeds) . vmap(values)`` of the kernel transform (:func:`jaxmdp.apply_p_rand` / :func:`jaxmdp.apply_p_lazy`)
  followed by ``lax.map(hardness.measures)`` over the grid (each member stops at its own convergence). The transform
  lists the states in the base order, whereas a construction from scratch with the noise enumerates them over the
  noisy outcome lists (``jaxmdp.transforms``); the paper's measures do not depend on the state order, so the two
  agree to round-off.
* scenarios 3-4, and scenarios 1-2 with ``variant="colosseum"``: every MDP of the grid is built from scratch (as the
  reference does), all are padded to common shapes with :func:`jaxmdp.stack` (padding changes no measure) and
  ``lax.map(hardness.measures)`` runs once over the stack: members of different sizes converge in different numbers
  of sweeps, and mapped (not vmapped) each stops at its own (docs/performance.md, Hardness measures). The colosseum
  variant needs the reference's own state order (its Gauss-Seidel sweeps and the reset-column quirk of its episodic
  continuous form depend on it), hence no transform. Episodic MDPs also need the reference's continuous forms, built on the host.

The raw measures are ``+inf`` where a diameter is infinite or a solver did not certify its value within its budget
(``converged`` tells which); :func:`normalize_measures` leaves such entries out of the minimum and maximum and maps
them to NaN.

Defaults (:data:`FAMILY_DEFAULTS`, :data:`NOISE_VALUES`): the paper gives no grids, so these are ours, chosen so that
every default grid runs in seconds to a minute on a CPU. The base parameters follow the reference's
hardness-analysis scripts in making the rewards stochastic (``make_reward_stochastic=True``); action randomisation
keeps the family default (it changes no measure). ``p_rand`` and ``p_lazy`` sweep ``0, 0.05, ..., 0.5``. The size
grids are listed per family below.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

import jaxmdp
from hardness.batched import map_measures
from hardness.measures import HardnessMeasures, measures, normalize
from jaxmdp._checks import Variant, check_int, check_range, check_variant
from jaxmdp.episodic import continuous_form, stack_continuous_forms
from jaxmdp.mdp import MDP
from jaxmdp.transforms import MAX_NOISE_PROBABILITY

__all__ = [
    "MEASURES",
    "SCENARIOS",
    "SCENARIO_4_P_RAND",
    "NOISE_VALUES",
    "FamilyDefaults",
    "FAMILY_DEFAULTS",
    "ScenarioSpec",
    "ScenarioGrid",
    "ScenarioResult",
    "scenario_spec",
    "prepare",
    "compute",
    "grid_mdps",
    "normalize_measures",
    "normalize_padded",
    "run_scenario",
    "sweep_p_rand",
    "sweep_p_lazy",
    "sweep_size",
]


#: The measures computed by every scenario, in :class:`hardness.HardnessMeasures` field order.
MEASURES: tuple[str, ...] = ("diameter", "value_norm", "sum_reciprocal_gaps")

#: Scenario number -> what it sweeps (``"size"`` stands for the family's size parameter).
SCENARIOS: Mapping[int, str] = MappingProxyType({1: "p_rand", 2: "p_lazy", 3: "size", 4: "size"})

#: The ``p_rand`` of scenario 4 (paper §3.2).
SCENARIO_4_P_RAND = 0.1

#: Default ``p_rand`` / ``p_lazy`` grid of scenarios 1-2: ``0, 0.05, ..., 0.5``.
NOISE_VALUES: tuple[float, ...] = tuple(round(0.05 * i, 4) for i in range(11))


@dataclasses.dataclass(frozen=True)
class FamilyDefaults:
    """Default parameters of a family in the scenarios.

    Attributes:
      params: parameters of the MDPs of every scenario (scenarios 1-2: the base MDP; scenarios 3-4: everything but
        the size).
      size_param: name of the family's size parameter (swept by scenarios 3-4).
      sizes: default values of ``size_param`` in scenarios 3-4.
    """

    params: Mapping[str, Any]
    size_param: str
    sizes: tuple[int, ...]


def _defaults(size_param: str, sizes: Sequence[int], **params: Any) -> FamilyDefaults:
    return FamilyDefaults(MappingProxyType(dict(make_reward_stochastic=True, **params)), size_param, tuple(sizes))


#: Per-family defaults. Number of states (docs/families.md §3): RiverSwim ``size``; DeepSea ``size(size+1)/2``;
#: SimpleGrid ``size^2``; FrozenLake the reachable non-hole cells (seed dependent); MiniGridEmpty ``4 size^2``;
#: MiniGridRooms ``4 (n_rooms rs^2 + 2k(k-1))``; Taxi ``free cells x n_locations^2``; MiniGridDoorKey grows as
#: ``size^4``.
FAMILY_DEFAULTS: Mapping[str, FamilyDefaults] = MappingProxyType(
    {
        "RiverSwim": _defaults("size", (5, 10, 15, 20, 25, 30), size=10),
        "DeepSea": _defaults("size", (4, 8, 12, 16, 20, 24), size=10),
        "SimpleGrid": _defaults("size", (4, 6, 8, 10, 12, 14), size=8),
        "FrozenLake": _defaults("size", (3, 4, 5, 6, 7, 8), size=5, p_frozen=0.8),
        "MiniGridEmpty": _defaults("size", (4, 5, 6, 7, 8, 9, 10), size=5),
        "MiniGridRooms": _defaults("room_size", (2, 3, 4, 5), room_size=3, n_rooms=4),
        "Taxi": _defaults("size", (4, 5, 6), size=4, length=1, n_locations=3),
        "MiniGridDoorKey": _defaults("size", (3, 4, 5), size=4),
    }
)


@dataclasses.dataclass(frozen=True)
class ScenarioSpec:
    """A validated scenario: what to build and sweep (made by :func:`scenario_spec`).

    ``parameter`` is ``"p_rand"``, ``"p_lazy"`` or the family's size parameter; ``values`` its grid; ``params`` the
    fixed construction parameters as sorted ``(name, value)`` pairs.
    """

    scenario: int
    family: str
    episodic: bool
    parameter: str
    values: tuple[float, ...] | tuple[int, ...]
    seeds: tuple[int, ...]
    params: tuple[tuple[str, Any], ...]
    variant: Variant
    gamma: float

    @property
    def setting(self) -> str:
        """``"episodic"`` or ``"continuous"``."""
        return "episodic" if self.episodic else "continuous"

    @property
    def uses_transform(self) -> bool:
        """Whether the grid is computed with the kernel transform over one base MDP per seed (module docstring)."""
        return self.scenario in (1, 2) and self.variant == "paper"

    def mdp_params(self, value: Any = None) -> dict[str, Any]:
        """Construction parameters of the MDP at grid value ``value`` (``None``: the base MDP of scenarios 1-2)."""
        out = dict(self.params)
        if value is not None:
            out[self.parameter] = value
        return out


def scenario_spec(
    scenario: int,
    family: str,
    *,
    episodic: bool,
    seeds: Sequence[int] = (0, 1, 2),
    values: Sequence[float] | None = None,
    params: Mapping[str, Any] | None = None,
    variant: Variant = "paper",
    gamma: float = 0.99,
) -> ScenarioSpec:
    """Validate a scenario and fill in the family defaults (:data:`FAMILY_DEFAULTS`).

    Args:
      scenario: 1 (``p_rand``), 2 (``p_lazy``), 3 (size) or 4 (size with ``p_rand = 0.1``).
      family: a registered family (:func:`jaxmdp.mdp_families`).
      episodic: the setting.
      seeds: distinct non-negative seeds.
      values: the grid of the swept parameter (distinct); default :data:`NOISE_VALUES` or the family's sizes.
      params: construction parameters; they *replace* the family defaults key by key. Scenario 4 sets ``p_rand`` to
        0.1 unless ``params`` sets it.
      variant: ``"paper"`` (default) or ``"colosseum"`` (the reference's numbers, :func:`hardness.measures`).
      gamma: discount factor of the value norm and the gap sum, in ``(0, 1)``.

    Raises:
      ValueError: naming the offending argument (unknown scenario, family or variant; duplicate or out-of-range
        values or seeds; ``params`` setting the swept parameter; a family without a lazy mechanic in scenario 2).
    """
    if scenario not in SCENARIOS:
        raise ValueError(f"scenario must be one of {sorted(SCENARIOS)}; got {scenario!r}")
    if family not in jaxmdp.families():
        raise ValueError(f"family must be one of {', '.join(jaxmdp.families())}; got {family!r}")
    check_variant(variant)
    check_range("gamma", gamma, 0.0, 1.0, low_open=True, high_open=True)
    defaults = FAMILY_DEFAULTS.get(family)
    if defaults is None and (params is None or (scenario in (3, 4) and values is None)):
        raise ValueError(
            f"family {family!r} has no defaults in hardness.analysis.scenarios.FAMILY_DEFAULTS: give params (and "
            "values for scenarios 3-4)"
        )

    seeds = tuple(check_int("seeds", s, 0) for s in seeds)
    if not seeds:
        raise ValueError("seeds must not be empty")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be distinct; got {list(seeds)}")

    swept = SCENARIOS[scenario]
    size_param = defaults.size_param if defaults is not None else "size"
    parameter = size_param if swept == "size" else swept
    merged = dict(defaults.params) if defaults is not None else {}
    merged.update(params or {})
    if parameter in (params or {}):
        raise ValueError(f"params must not set {parameter!r}: scenario {scenario} sweeps it (give values instead)")
    if swept == "size":
        merged.pop(parameter, None)
        if scenario == 4:
            merged.setdefault("p_rand", SCENARIO_4_P_RAND)
    if values is None:
        values = defaults.sizes if swept == "size" else NOISE_VALUES
    values = list(values)
    if not values:
        raise ValueError("values must not be empty")
    if swept == "size":
        values = tuple(check_int("values", v, 1) for v in values)
    else:
        checked = []
        for v in values:
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not (
                0.0 <= float(v) < MAX_NOISE_PROBABILITY
            ):
                raise ValueError(f"values of {parameter} must lie in [0, {MAX_NOISE_PROBABILITY}); got {v!r}")
            checked.append(float(v))
        values = tuple(checked)
    if len(set(values)) != len(values):
        raise ValueError(f"values must be distinct; got {list(values)}")

    spec = ScenarioSpec(
        scenario=scenario,
        family=family,
        episodic=bool(episodic),
        parameter=parameter,
        values=values,
        seeds=seeds,
        params=tuple(sorted(merged.items())),
        variant=variant,
        gamma=float(gamma),
    )
    # Let the family validate its parameters once, on the cheapest MDP of the grid; a p_lazy sweep also checks that
    # the family has a lazy mechanic (DeepSea has none).
    probe = min(values) if swept == "size" else (max(values) if swept == "p_lazy" else None)
    jaxmdp.make(family, episodic=spec.episodic, seed=seeds[0], **spec.mdp_params(probe))
    return spec


# ---------------------------------------------------------------------------------------------------------------
# Building and computing a grid
# ---------------------------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class ScenarioGrid:
    """The MDPs of a scenario for some seeds, padded to common shapes and stacked (made by :func:`prepare`).

    ``batch`` has leading axis ``seeds x members``: one base MDP per seed when ``spec.uses_transform``, else one MDP
    per grid value. ``forms`` holds the reference's continuous forms (colosseum variant, episodic) or ``None``.
    ``n_states[i, j]``: number of states of seed ``seeds[i]`` at ``spec.values[j]`` (without padding).
    """

    spec: ScenarioSpec
    seeds: tuple[int, ...]
    batch: MDP
    forms: Any
    n_states: np.ndarray

    def take(self, seeds: Sequence[int]) -> "ScenarioGrid":
        """The grid of a subset of its seeds (repeats allowed), keeping the padded shapes, so that chunks of the
        same size share one compiled program."""
        pos = [self.seeds.index(s) if s in self.seeds else -1 for s in seeds]
        if not pos or min(pos) < 0:
            raise ValueError(f"seeds must be a non-empty subset of {list(self.seeds)}; got {list(seeds)}")
        members = 1 if self.spec.uses_transform else len(self.spec.values)
        rows = np.asarray([p * members + j for p in pos for j in range(members)])
        # Gathered on the host: an eager device gather compiles a program per array shape.
        pick = lambda x: jax.device_put(np.asarray(x)[rows])  # noqa: E731
        return dataclasses.replace(
            self,
            seeds=tuple(seeds),
            batch=jax.tree.map(pick, self.batch),
            forms=None if self.forms is None else jax.tree.map(pick, self.forms),
            n_states=self.n_states[np.asarray(pos)],
        )


def prepare(spec: ScenarioSpec, seeds: Sequence[int] | None = None) -> ScenarioGrid:
    """Build (host side) the MDPs of ``seeds`` (default all of ``spec.seeds``) and stack them for :func:`compute`."""
    seeds = tuple(spec.seeds if seeds is None else seeds)
    unknown = [s for s in seeds if s not in spec.seeds]
    if unknown or not seeds:
        raise ValueError(f"seeds must be a non-empty subset of the spec's seeds {list(spec.seeds)}; got {list(seeds)}")
    if spec.uses_transform:
        mdps = [jaxmdp.make(spec.family, episodic=spec.episodic, seed=s, **spec.mdp_params()) for s in seeds]
        n_states = np.repeat([[m.n_states] for m in mdps], len(spec.values), axis=1)
    else:
        mdps = [
            jaxmdp.make(spec.family, episodic=spec.episodic, seed=s, **spec.mdp_params(v))
            for s in seeds
            for v in spec.values
        ]
        n_states = np.asarray([m.n_states for m in mdps]).reshape(len(seeds), len(spec.values))
    forms = None
    if spec.variant == "colosseum" and spec.episodic:
        forms = stack_continuous_forms([continuous_form(m) for m in mdps])
    batch = jaxmdp.stack(mdps).strip()
    return ScenarioGrid(spec=spec, seeds=seeds, batch=batch, forms=forms, n_states=n_states)


@functools.partial(jax.jit, static_argnames=("kind",))
def _transformed(bases: MDP, values: jax.Array, kind: str) -> MDP:
    transform = jaxmdp.apply_p_rand if kind == "p_rand" else jaxmdp.apply_p_lazy
    grid = jax.vmap(lambda base: jax.vmap(lambda v: transform(base, v))(values))(bases)
    return jax.tree.map(lambda x: x.reshape(-1, *x.shape[2:]), grid)


@functools.partial(jax.jit, static_argnames=("kind", "variant", "gamma"))
def _transform_grid(bases: MDP, values: jax.Array, kind: str, variant: str, gamma: float) -> HardnessMeasures:
    """The measures of :func:`_transformed`'s grid, ``[n_seeds * n_values]``, mapped over its members (``lax.map``:
    each member's solvers stop at its own convergence): vmapped in lockstep, every member would run until the slowest
    converged, which costs more on a CPU for the same numbers (docs/performance.md, Hardness measures)."""
    return jax.lax.map(lambda m: measures(m, gamma, variant=variant), _transformed(bases, values, kind))


def grid_mdps(grid: ScenarioGrid) -> MDP:
    """Every MDP of a prepared grid as one stacked batch ``[n_seeds * n_values]`` (seed-major), e.g. to run agents
    on them: the kernel transform of each base (scenarios 1-2, ``variant="paper"``) or the built MDPs."""
    spec = grid.spec
    if not spec.uses_transform:
        return grid.batch
    return _transformed(grid.batch, jnp.asarray(spec.values, grid.batch.dtype), spec.parameter)


def compute(grid: ScenarioGrid) -> dict[str, np.ndarray]:
    """Run the batched measures of a prepared grid (module docstring): one jitted call.

    Returns ``{measure: value[n_seeds, n_values], measure + "_converged": bool[n_seeds, n_values]}`` for every
    measure of :data:`MEASURES`, plus ``"n_states"``.
    """
    spec = grid.spec
    n, V = len(grid.seeds), len(spec.values)
    if spec.uses_transform:
        values = jnp.asarray(spec.values, grid.batch.dtype)
        out = _transform_grid(grid.batch, values, spec.parameter, spec.variant, spec.gamma)
    else:
        out = map_measures(grid.batch, grid.forms, spec.gamma, spec.variant)
    result: dict[str, np.ndarray] = {"n_states": grid.n_states.copy()}
    for name in MEASURES:
        m = getattr(out, name)
        result[name] = np.asarray(m.value, np.float64).reshape(n, V)
        result[name + "_converged"] = np.asarray(m.converged, bool).reshape(n, V)
    return result


def normalize_measures(raw: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Min-max normalisation of every measure across all seeds and values of the sweep (paper App. E) with
    :func:`hardness.normalize`: ``(x - min) / (max - min)``, 0.5 for a set whose range is below ``1e-4``; non-finite
    entries are left out of the minimum and maximum and become NaN."""
    return {name: normalize_padded(raw[name]) for name in MEASURES}


def normalize_padded(values: np.ndarray) -> np.ndarray:
    """:func:`hardness.normalize` over all entries of ``values`` in float32, returned as float64 of the same shape.

    The entries are padded with NaN to a power of two (at least 64) first: non-finite entries take no part in the
    minimum and maximum, so the result is the same, and tables that grow seed by seed share a few compiled programs
    instead of one per size."""
    flat = np.asarray(values, np.float32).ravel()
    padded = np.full(max(64, 1 << max(flat.size - 1, 0).bit_length()), np.nan, np.float32)
    padded[: flat.size] = flat
    out = np.asarray(normalize(jax.device_put(padded)), np.float64)
    return out[: flat.size].reshape(np.shape(values))


# ---------------------------------------------------------------------------------------------------------------
# Whole scenarios
# ---------------------------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class ScenarioResult:
    """Raw and normalised measures of a scenario, arrays ``[n_seeds, n_values]`` indexed by ``spec.seeds`` and
    ``spec.values``.

    Attributes:
      spec: the scenario.
      n_states: number of states of every MDP of the grid.
      raw: measure name -> value (``+inf`` where infinite or not certified).
      converged: measure name -> whether the solver certified the value.
      normalized: measure name -> App. E normalisation of ``raw`` (NaN where ``raw`` is not finite).
    """

    spec: ScenarioSpec
    n_states: np.ndarray
    raw: Mapping[str, np.ndarray]
    converged: Mapping[str, np.ndarray]
    normalized: Mapping[str, np.ndarray]

    @property
    def x(self) -> np.ndarray:
        """The figure's x values: the swept probability, or the mean number of states over seeds (scenarios 3-4,
        as the reference plots size sweeps against the number of states)."""
        if self.spec.scenario in (3, 4):
            return self.n_states.mean(axis=0)
        return np.asarray(self.spec.values, np.float64)


def run_scenario(scenario: int, family: str, *, episodic: bool, **kwargs: Any) -> ScenarioResult:
    """Build and compute a whole scenario in one batched call (arguments as :func:`scenario_spec`)."""
    spec = scenario_spec(scenario, family, episodic=episodic, **kwargs)
    raw = compute(prepare(spec))
    return ScenarioResult(
        spec=spec,
        n_states=raw["n_states"],
        raw={k: raw[k] for k in MEASURES},
        converged={k: raw[k + "_converged"] for k in MEASURES},
        normalized=normalize_measures(raw),
    )


def sweep_p_rand(family: str, *, episodic: bool, **kwargs: Any) -> ScenarioResult:
    """Scenario 1: the measures against ``p_rand`` (:func:`run_scenario`)."""
    return run_scenario(1, family, episodic=episodic, **kwargs)


def sweep_p_lazy(family: str, *, episodic: bool, **kwargs: Any) -> ScenarioResult:
    """Scenario 2: the measures against ``p_lazy`` (:func:`run_scenario`)."""
    return run_scenario(2, family, episodic=episodic, **kwargs)


def sweep_size(family: str, *, episodic: bool, p_rand: float = 0.0, **kwargs: Any) -> ScenarioResult:
    """The measures against the family's size parameter (:func:`run_scenario`): scenario 3 with ``p_rand = 0``,
    scenario 4 otherwise (the paper's scenario 4 uses ``p_rand = 0.1``)."""
    if isinstance(p_rand, bool) or not isinstance(p_rand, (int, float)) or not (
        0.0 <= float(p_rand) < MAX_NOISE_PROBABILITY
    ):
        raise ValueError(f"p_rand must lie in [0, {MAX_NOISE_PROBABILITY}); got {p_rand!r}")
    params = dict(kwargs.pop("params", None) or {})
    if "p_rand" in params:
        raise ValueError("give p_rand as the argument of sweep_size, not in params")
    params["p_rand"] = float(p_rand) if p_rand > 0 else None
    return run_scenario(4 if p_rand > 0 else 3, family, episodic=episodic, params=params, **kwargs)
