"""hardness.analysis.scenarios (paper §3.2, App. D, App. E) against independent computations.

* Scenarios 1-2 (``variant="paper"``: one base MDP per seed, vmapped kernel transform) equal building every noisy MDP
  from scratch with ``jaxmdp.make`` and calling ``hardness.measures`` on it alone, one at a time: scenario 1 on
  episodic FrozenLake (seeds of different sizes, so the bases are padded), scenario 2 on continuous RiverSwim. The
  from-scratch MDP lists its states in another order (``jaxmdp.transforms``), so continuous values come from
  differently ordered float32 solves: agreement to ``RTOL``.
* Scenarios 3-4 (and the colosseum variant, with the reference's continuous forms): the sizes padded into one batch
  equal each MDP alone; scenario 4 has ``p_rand = 0.1``; the x axis is the number of states.
* ``normalize_measures`` equals the App. E formula written out in numpy.
* ``scenario_spec``: defaults, and every ``ValueError`` names its parameter.
* ``ScenarioGrid.take`` picks the rows of the seeds asked for; chunks padded with copies of a seed change nothing.

Grids are tiny (FrozenLake 3x3, RiverSwim 4-5, DeepSea 3-4), and the FrozenLake scenario-1 grid is the one
``tests/test_sweep_cli.py`` runs, so the two files share compiled programs. Compilation dominates the run time:
each new shape of the batched measures costs seconds, hence few grids.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

import hardness
import jaxmdp
from hardness.analysis import scenarios
from hardness.analysis.scenarios import MEASURES
from jaxmdp.episodic import continuous_form

from hardness_helpers import normalize_by_hand

# Paper variant, from scratch vs transform: the states are ordered differently, so the dense float32 solves of the
# continuous values round differently (measured: <= 3e-6 relative on these MDPs). Colosseum: same MDPs, same
# operations, only the vmap differs.
RTOL = {"paper": 1e-5, "colosseum": 2e-6}

# FrozenLake 3x3 lakes of seeds 0, 1 and 3 have 8, 9 and 7 reachable non-hole cells: the seeds differ in measures
# and in shape, so stacking them pads.
FL_SEEDS = (0, 1, 3)
FL_STATES = {0: 8, 1: 9, 3: 7}
FL_PARAMS = dict(size=3, p_frozen=0.8, make_reward_stochastic=True)  # the family defaults with size=3
FL_VALUES = (0.0, 0.2)


def alone(mdp: jaxmdp.MDP, variant: str = "paper", gamma: float = 0.99):
    """``(values[3], converged[3])`` of one MDP measured on its own."""
    r = hardness.measures(mdp, gamma, variant=variant)
    values = np.array([float(getattr(r, k).value) for k in MEASURES])
    return values, np.array([bool(getattr(r, k).converged) for k in MEASURES])


def stacked(raw: dict) -> np.ndarray:
    """``[n_seeds, n_values, 3]`` of the measures of a :func:`scenarios.compute` output."""
    return np.stack([raw[k] for k in MEASURES], axis=-1)


def expected_grid(family, episodic, seeds, values, parameter, variant="paper", common_shape=False, **params):
    """Every ``(seed, value)`` built from scratch with ``jaxmdp.make`` and measured alone, one at a time:
    ``(values[n_seeds, n_values, 3], converged[...], n_states[n_seeds, n_values])``.

    ``common_shape=True`` pads each MDP (alone, no batch) to the largest ``S, A, K, H`` of the grid first, so that
    every call reuses one compiled program; padding changes no measure (tests/test_hardness_measures.py).
    """
    mdps = [[jaxmdp.make(family, episodic=episodic, seed=s, **params, **{parameter: v}) for v in values] for s in seeds]
    flat = [m for row in mdps for m in row]
    if common_shape:
        S, A, K = (max(m.succ.shape[i] for m in flat) for i in range(3))
        H = max(m.H for m in flat) if episodic else None
        pad = lambda m: jaxmdp.pad(m.strip(), S, A, K, H)  # noqa: E731
    else:
        pad = lambda m: m  # noqa: E731
    out = [[alone(pad(m), variant) for m in row] for row in mdps]
    vals = np.array([[o[0] for o in row] for row in out])
    conv = np.array([[o[1] for o in row] for row in out])
    return vals, conv, np.array([[m.n_states for m in row] for row in mdps])


# ---------------------------------------------------------------------------------------------------------------
# Scenarios 1-2: the transform over one base MDP per seed equals the MDPs built from scratch
# ---------------------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def frozen_lake_p_rand():
    """Scenario 1, FrozenLake 3x3 episodic, three seeds of different sizes, the whole grid in one call."""
    spec = scenarios.scenario_spec(1, "FrozenLake", episodic=True, seeds=FL_SEEDS, values=FL_VALUES,
                                   params=dict(size=3))
    grid = scenarios.prepare(spec)
    return spec, grid, scenarios.compute(grid)


def test_scenario1_episodic_transform_equals_from_scratch(frozen_lake_p_rand):
    """Scenario 1, episodic, seeds of different sizes (the bases are padded into one batch)."""
    spec, grid, raw = frozen_lake_p_rand
    assert spec.uses_transform and spec.parameter == "p_rand" and spec.values == FL_VALUES
    assert grid.batch.T.shape == (3, 9, 4, 9)  # one padded base MDP per seed, not one per value
    want, conv, n = expected_grid("FrozenLake", True, FL_SEEDS, FL_VALUES, "p_rand", common_shape=True, **FL_PARAMS)
    np.testing.assert_array_equal(n[:, 0], [FL_STATES[s] for s in FL_SEEDS])
    np.testing.assert_array_equal(raw["n_states"], n)
    np.testing.assert_allclose(stacked(raw), want, rtol=RTOL["paper"])
    assert conv.all() and all(raw[k + "_converged"].all() for k in MEASURES)
    # The seeds differ (a mix-up of rows would show) and p_rand changes every measure.
    assert np.ptp(raw["diameter"][:, 1]) > 1.0
    assert np.all(np.abs(stacked(raw)[:, 1] - stacked(raw)[:, 0]) > 1e-3 * np.abs(stacked(raw)[:, 0]))


def test_scenario2_continuous_transform_equals_from_scratch():
    """Scenario 2, continuous (the exact discounted solves of the paper variant), through run_scenario."""
    values = (0.0, 0.1, 0.3)
    res = scenarios.sweep_p_lazy("RiverSwim", episodic=False, seeds=(0, 1), values=values, params=dict(size=5))
    assert res.spec.scenario == 2 and res.spec.uses_transform
    want, conv, n = expected_grid("RiverSwim", False, (0, 1), values, "p_lazy", common_shape=True, size=5,
                                  make_reward_stochastic=True)
    got = np.stack([res.raw[k] for k in MEASURES], axis=-1)
    np.testing.assert_allclose(got, want, rtol=RTOL["paper"])
    np.testing.assert_array_equal(res.n_states, n)
    np.testing.assert_array_equal(n, 5)
    assert conv.all() and all(res.converged[k].all() for k in MEASURES)
    assert np.all(np.abs(got[:, 2] - got[:, 0]) > 1e-4 * np.maximum(np.abs(got[:, 0]), 1.0))
    np.testing.assert_array_equal(res.x, values)
    for k in MEASURES:  # normalised over both seeds and all values at once
        np.testing.assert_allclose(res.normalized[k], normalize_by_hand(res.raw[k]), atol=1e-6)


# ---------------------------------------------------------------------------------------------------------------
# Scenarios 3-4: sizes padded into one batch equal each MDP alone
# ---------------------------------------------------------------------------------------------------------------


def test_scenario3_sizes_padded_equal_each_alone():
    sizes = (3, 4)
    res = scenarios.sweep_size("DeepSea", episodic=False, seeds=(0,), values=sizes)
    assert res.spec.scenario == 3 and res.spec.parameter == "size" and not res.spec.uses_transform
    assert dict(res.spec.params)["p_rand"] is None
    want, conv, n = expected_grid("DeepSea", False, (0,), sizes, "size", make_reward_stochastic=True)
    np.testing.assert_allclose(np.stack([res.raw[k] for k in MEASURES], -1), want, rtol=RTOL["paper"])
    assert conv.all() and all(res.converged[k].all() for k in MEASURES)
    # DeepSea of size n has n(n+1)/2 states; the figure's x axis is the number of states.
    np.testing.assert_array_equal(res.n_states, [[6, 10]])
    np.testing.assert_array_equal(res.x, [6.0, 10.0])
    # By hand: the longest shortest path of a deterministic DeepSea of size n runs from (0, 1) to the bottom-right
    # corner (n-1, n-1): n-2 steps down to the last row, one back to the start, n-1 down the diagonal: 2n - 2.
    np.testing.assert_allclose(res.raw["diameter"], [[4.0, 6.0]], rtol=1e-6)


@pytest.fixture(scope="module")
def river_swim_sizes():
    """Scenario 4, colosseum variant, RiverSwim episodic sizes 4 and 5: one row per (seed, size), and the reference's
    continuous forms of the episodic MDPs stacked alongside."""
    spec = scenarios.scenario_spec(4, "RiverSwim", episodic=True, seeds=(0, 2), values=(4, 5), variant="colosseum")
    return spec, scenarios.prepare(spec)


def test_scenario4_colosseum_episodic_has_p_rand_0_1_and_equals_each_alone(river_swim_sizes):
    spec, grid = river_swim_sizes
    assert dict(spec.params)["p_rand"] == scenarios.SCENARIO_4_P_RAND == 0.1 and not spec.uses_transform
    raw = scenarios.compute(grid)
    # Padded alone, one compiled program (the unpadded comparison is scenario 3's).
    want, conv, n = expected_grid("RiverSwim", True, (0, 2), (4, 5), "size", "colosseum", common_shape=True,
                                  p_rand=0.1, make_reward_stochastic=True)
    np.testing.assert_allclose(stacked(raw), want, rtol=RTOL["colosseum"])
    np.testing.assert_array_equal(raw["n_states"], [[4, 5], [4, 5]])
    assert conv.all() and all(raw[k + "_converged"].all() for k in MEASURES)


def test_x_is_mean_number_of_states_over_seeds():
    """Scenarios 3-4 plot against the mean number of states over seeds; scenarios 1-2 against the values."""
    spec3 = scenarios.scenario_spec(3, "FrozenLake", episodic=True, seeds=(0, 1, 3), values=(3, 4))
    n = np.array([[8, 13], [9, 14], [7, 16]])
    res = scenarios.ScenarioResult(spec=spec3, n_states=n, raw={}, converged={}, normalized={})
    np.testing.assert_allclose(res.x, [8.0, 43.0 / 3.0])
    spec1 = dataclasses.replace(spec3, scenario=1, parameter="p_rand", values=(0.0, 0.25))
    res1 = scenarios.ScenarioResult(spec=spec1, n_states=n, raw={}, converged={}, normalized={})
    np.testing.assert_array_equal(res1.x, [0.0, 0.25])


def test_sweep_helpers_dispatch_to_the_right_scenario(monkeypatch):
    seen = []

    def fake_prepare(spec, seeds=None):
        seen.append(spec)
        return spec

    def fake_compute(spec):
        shape = (len(spec.seeds), len(spec.values))
        out = {"n_states": np.full(shape, 5)}
        for k in MEASURES:
            out[k] = np.arange(np.prod(shape), dtype=float).reshape(shape)
            out[k + "_converged"] = np.ones(shape, bool)
        return out

    monkeypatch.setattr(scenarios, "prepare", fake_prepare)
    monkeypatch.setattr(scenarios, "compute", fake_compute)
    kw = dict(episodic=False, seeds=(0,), params=dict(size=5))
    assert scenarios.sweep_p_rand("RiverSwim", **kw).spec.parameter == "p_rand"
    assert scenarios.sweep_p_lazy("RiverSwim", **kw).spec.parameter == "p_lazy"
    res3 = scenarios.sweep_size("RiverSwim", episodic=False, seeds=(0,), values=(4, 5))
    res4 = scenarios.sweep_size("RiverSwim", episodic=False, seeds=(0,), values=(4, 5), p_rand=0.25)
    assert [s.scenario for s in seen] == [1, 2, 3, 4]
    assert dict(res3.spec.params)["p_rand"] is None and dict(res4.spec.params)["p_rand"] == 0.25
    assert seen[0].values == scenarios.NOISE_VALUES
    np.testing.assert_allclose(res4.normalized["diameter"], [[0.0, 1.0]])
    with pytest.raises(ValueError, match="p_rand"):
        scenarios.sweep_size("RiverSwim", episodic=False, p_rand=1.0)
    with pytest.raises(ValueError, match="p_rand"):
        scenarios.sweep_size("RiverSwim", episodic=False, p_rand=-0.1)
    with pytest.raises(ValueError, match="p_rand"):
        scenarios.sweep_size("RiverSwim", episodic=False, params=dict(p_rand=0.1))


# ---------------------------------------------------------------------------------------------------------------
# ScenarioGrid.take and chunks
# ---------------------------------------------------------------------------------------------------------------


def test_take_transform_grid_picks_rows(frozen_lake_p_rand):
    spec, grid, raw = frozen_lake_p_rand
    sub = grid.take([3, 0, 3])
    assert sub.seeds == (3, 0, 3) and sub.batch.T.shape == (3, 9, 4, 9)  # keeps the padded shape
    np.testing.assert_array_equal(sub.n_states, [[7, 7], [8, 8], [7, 7]])
    for row, seed in enumerate(sub.seeds):
        m = jaxmdp.make("FrozenLake", episodic=True, seed=seed, **FL_PARAMS)
        S = m.n_states
        np.testing.assert_array_equal(np.asarray(sub.batch.T[row, :S, :, :S]), np.asarray(m.T))
        np.testing.assert_array_equal(np.asarray(sub.batch.R[row, :S]), np.asarray(m.R))
        np.testing.assert_array_equal(np.asarray(sub.batch.state_mask[row]), np.arange(9) < S)
    with pytest.raises(ValueError, match="seeds"):
        grid.take([2])
    with pytest.raises(ValueError, match="seeds"):
        grid.take([])


def test_take_size_grid_moves_every_value_of_a_seed(river_swim_sizes):
    """Without the transform a seed owns one row per value (and one continuous form): take moves the whole block.
    RiverSwim's seeds permute the actions, so rows of different seeds differ."""
    spec, grid = river_swim_sizes
    assert grid.batch.T.shape == (4, 5, 2, 5) and grid.forms is not None
    sub = grid.take([2, 0, 2])
    assert sub.batch.T.shape == (6, 5, 2, 5)
    for i, seed in enumerate((2, 0, 2)):
        for j, size in enumerate((4, 5)):
            m = jaxmdp.make("RiverSwim", episodic=True, seed=seed, size=size, p_rand=0.1,
                            make_reward_stochastic=True)
            cf = continuous_form(m)
            row = 2 * i + j
            assert sub.n_states[i, j] == size
            np.testing.assert_array_equal(np.asarray(sub.batch.T[row, :size, :, :size]), np.asarray(m.T))
            np.testing.assert_array_equal(np.asarray(sub.batch.state_mask[row]), np.arange(5) < size)
            n = cf.n_rows
            np.testing.assert_array_equal(np.asarray(sub.forms.R[row, :n]), np.asarray(cf.R))
            np.testing.assert_array_equal(np.asarray(sub.forms.pair_s[row, :n]), np.asarray(cf.pair_s))
            np.testing.assert_array_equal(np.asarray(sub.forms.row_mask[row]), np.arange(sub.forms.n_rows) < n)
    assert not np.array_equal(np.asarray(sub.batch.T[0]), np.asarray(sub.batch.T[2]))  # seeds 2 and 0 differ
    with pytest.raises(ValueError, match="seeds"):
        grid.take([1])
    with pytest.raises(ValueError, match="seeds"):
        scenarios.prepare(spec, [5])
    with pytest.raises(ValueError, match="seeds"):
        scenarios.prepare(spec, [])


def test_padded_chunk_copies_change_nothing(frozen_lake_p_rand):
    """The CLI fills a short last chunk with copies of its first seed: the real rows are unchanged."""
    spec, grid, raw = frozen_lake_p_rand
    full = stacked(raw)
    a = stacked(scenarios.compute(grid.take([3, 3])))
    b = stacked(scenarios.compute(grid.take([1, 0])))
    np.testing.assert_allclose(a[0], full[2], rtol=1e-6)
    np.testing.assert_allclose(a[1], full[2], rtol=1e-6)
    np.testing.assert_allclose(b, full[[1, 0]], rtol=1e-6)


# ---------------------------------------------------------------------------------------------------------------
# App. E normalisation
# ---------------------------------------------------------------------------------------------------------------


def test_normalize_measures_app_e_by_hand():
    rng = np.random.default_rng(5)
    raw = {
        "diameter": rng.uniform(3.0, 40.0, size=(3, 5)),
        "value_norm": rng.uniform(0.0, 2.0, size=(3, 5)),
        "sum_reciprocal_gaps": rng.uniform(100.0, 900.0, size=(3, 5)),
        "n_states": np.ones((3, 5), int),  # ignored
    }
    raw["diameter"][1, 2] = np.inf  # an infinite diameter
    raw["value_norm"][0, 0] = np.nan
    raw["sum_reciprocal_gaps"][2, 4] = -np.inf
    out = scenarios.normalize_measures(raw)
    assert set(out) == set(MEASURES)
    for k in MEASURES:
        want = normalize_by_hand(raw[k])
        np.testing.assert_array_equal(np.isnan(out[k]), np.isnan(want))
        np.testing.assert_allclose(out[k], want, atol=1e-6)
        assert out[k].dtype == np.float64 and out[k].shape == (3, 5)
    # Min and max over all seeds and values at once (App. E): exactly one 0 and one 1 per measure.
    for k in MEASURES:
        finite = out[k][np.isfinite(out[k])]
        assert finite.min() == pytest.approx(0.0, abs=1e-6) and finite.max() == pytest.approx(1.0, abs=1e-6)


def test_normalize_measures_half_rule_and_all_infinite():
    base = np.array([[2.0, 2.0 + 2.0**-16], [2.0, 2.0]])  # range 1.5e-5 < 1e-4
    wide = np.array([[2.0, 2.0 + 2.0**-12], [2.0 + 2.0**-13, 2.0]])  # range 2.4e-4 >= 1e-4
    raw = {"diameter": base, "value_norm": wide, "sum_reciprocal_gaps": np.full((2, 2), np.inf)}
    out = scenarios.normalize_measures(raw)
    np.testing.assert_array_equal(out["diameter"], np.full((2, 2), 0.5))
    np.testing.assert_allclose(out["value_norm"], [[0.0, 1.0], [0.5, 0.0]], atol=1e-6)
    assert np.isnan(out["sum_reciprocal_gaps"]).all()
    raw["diameter"] = np.array([[5.0, np.inf], [5.0, 5.0]])
    np.testing.assert_array_equal(scenarios.normalize_measures(raw)["diameter"], [[0.5, np.nan], [0.5, 0.5]])


@pytest.mark.parametrize("n", [1, 7, 64, 65, 130])
def test_normalize_padded_is_bit_identical_to_unpadded(n):
    # The NaN padding to a power of two must change no bit of the float32 normalisation of the real entries.
    rng = np.random.default_rng(n)
    x = rng.uniform(-3.0, 50.0, size=(n,))
    x[:: max(n // 3, 1)][1:2] = np.inf
    want = np.asarray(hardness.normalize(jnp.asarray(x, jnp.float32)), np.float64)
    got = scenarios.normalize_padded(x.reshape(1, n))
    assert got.shape == (1, n) and got.dtype == np.float64
    np.testing.assert_array_equal(got[0], want)


# ---------------------------------------------------------------------------------------------------------------
# scenario_spec: defaults and validation
# ---------------------------------------------------------------------------------------------------------------


def test_spec_defaults():
    s1 = scenarios.scenario_spec(1, "RiverSwim", episodic=False)
    assert s1.values == scenarios.NOISE_VALUES
    assert s1.seeds == (0, 1, 2) and s1.gamma == 0.99 and s1.variant == "paper" and s1.setting == "continuous"
    assert dict(s1.params) == dict(size=10, make_reward_stochastic=True)
    assert s1.mdp_params(0.3) == dict(size=10, make_reward_stochastic=True, p_rand=0.3)
    assert s1.mdp_params() == dict(size=10, make_reward_stochastic=True)
    s2 = scenarios.scenario_spec(2, "SimpleGrid", episodic=True, params=dict(size=4, make_reward_stochastic=False))
    assert s2.parameter == "p_lazy" and s2.setting == "episodic"
    assert dict(s2.params) == dict(size=4, make_reward_stochastic=False)  # params replace defaults key by key
    s3 = scenarios.scenario_spec(3, "MiniGridRooms", episodic=True, values=(2,))
    assert s3.parameter == "room_size" and "room_size" not in dict(s3.params)
    assert dict(s3.params) == dict(n_rooms=4, make_reward_stochastic=True)
    assert scenarios.scenario_spec(3, "DeepSea", episodic=False).values == (4, 8, 12, 16, 20, 24)
    s4 = scenarios.scenario_spec(4, "DeepSea", episodic=False, values=(3,))
    assert dict(s4.params)["p_rand"] == 0.1
    s4b = scenarios.scenario_spec(4, "DeepSea", episodic=False, values=(3,), params=dict(p_rand=0.3))
    assert dict(s4b.params)["p_rand"] == 0.3
    assert s4.mdp_params(5) == dict(make_reward_stochastic=True, p_rand=0.1, size=5)
    # numpy scalars are accepted and converted
    s = scenarios.scenario_spec(1, "RiverSwim", episodic=False, seeds=np.array([4, 2]), values=np.array([0.0, 0.1]),
                                params=dict(size=5))
    assert s.seeds == (4, 2) and s.values == (0.0, 0.1) and type(s.values[1]) is float


def _spec(**kw):
    args = dict(scenario=1, family="RiverSwim", episodic=False, params=dict(size=5))
    args.update(kw)
    return scenarios.scenario_spec(args.pop("scenario"), args.pop("family"), **args)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(scenario=5), "scenario"),
        (dict(scenario=0), "scenario"),
        (dict(family="RiverSwimm"), "family"),
        (dict(variant="reference"), "variant"),
        (dict(gamma=1.0), "gamma"),
        (dict(gamma=0.0), "gamma"),
        (dict(gamma=-0.5), "gamma"),
        (dict(gamma="0.9"), "gamma"),
        (dict(seeds=()), "seeds"),
        (dict(seeds=(0, 1, 0)), "seeds"),
        (dict(seeds=(-1,)), "seeds"),
        (dict(seeds=(1.0,)), "seeds"),
        (dict(seeds=(True,)), "seeds"),
        (dict(values=()), "values"),
        (dict(values=(0.1, 0.2, 0.1)), "values"),
        (dict(values=(-0.1,)), "values of p_rand"),
        (dict(values=(0.9999,)), "values of p_rand"),
        (dict(values=(1.0,)), "values of p_rand"),
        (dict(values=(np.nan,)), "values of p_rand"),
        (dict(values=(True,)), "values of p_rand"),
        (dict(values=("0.1",)), "values of p_rand"),
        (dict(scenario=2, values=(0.5, 1.2)), "values of p_lazy"),
        (dict(scenario=3, values=(0,)), "values"),
        (dict(scenario=3, values=(4, 4)), "values"),
        (dict(scenario=3, values=(4.5,)), "values"),
        (dict(params=dict(size=5, p_rand=0.1)), "p_rand"),
        (dict(scenario=2, params=dict(size=5, p_lazy=0.1)), "p_lazy"),
        (dict(scenario=3, params=dict(size=5), values=(4,)), "size"),
        (dict(scenario=4, family="MiniGridRooms", params=dict(room_size=3), values=(2,)), "room_size"),
        (dict(scenario=2, family="DeepSea", params=dict(size=4), values=(0.0, 0.1)), "p_lazy"),
        (dict(params=dict(size=1)), "size"),  # the family's own check, on the probe MDP
        (dict(params=dict(sise=5)), "sise"),
    ],
)
def test_spec_errors_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError) as err:
        _spec(**kwargs)
    assert name in str(err.value)


def test_spec_of_family_without_defaults(monkeypatch):
    """A registered family with no FAMILY_DEFAULTS entry needs explicit params (and sizes for scenarios 3-4)."""
    from jaxmdp import registry

    monkeypatch.setitem(registry._REGISTRY, "TestRiver", registry._REGISTRY["RiverSwim"])
    with pytest.raises(ValueError, match="FAMILY_DEFAULTS"):
        scenarios.scenario_spec(1, "TestRiver", episodic=False)
    with pytest.raises(ValueError, match="values"):
        scenarios.scenario_spec(3, "TestRiver", episodic=False, params=dict(p_rand=None))
    spec = scenarios.scenario_spec(3, "TestRiver", episodic=False, params=dict(p_rand=None), values=(4, 5))
    assert spec.parameter == "size" and spec.values == (4, 5) and dict(spec.params) == dict(p_rand=None)
    spec = scenarios.scenario_spec(1, "TestRiver", episodic=False, params=dict(size=4))
    assert spec.values == scenarios.NOISE_VALUES and dict(spec.params) == dict(size=4)


def test_family_defaults_are_valid_and_cheap_to_state():
    """Every default names a registered family and a size parameter outside its params; NOISE_VALUES is 0..0.5."""
    np.testing.assert_allclose(scenarios.NOISE_VALUES, np.linspace(0.0, 0.5, 11), atol=1e-12)
    assert dict(scenarios.SCENARIOS) == {1: "p_rand", 2: "p_lazy", 3: "size", 4: "size"}
    for family, d in scenarios.FAMILY_DEFAULTS.items():
        assert family in jaxmdp.families()
        assert d.params["make_reward_stochastic"] is True
        assert d.size_param in d.params and list(d.sizes) == sorted(set(d.sizes))
