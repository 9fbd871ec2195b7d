"""Emission maps (paper App. A.2 and App. C's emission-map tables; benchmark.md §5).

Shapes follow the spec's table for every family and both settings; values are checked against hand-worked grids (the
paper's DeepSea and SimpleGrid examples, the spec's worked examples) and against an independent decoding of the text
renderings; the linear maps against value functions computed here with numpy in float64.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import nightly_beyond

import jaxmdp
from jaxmdp.blockmdp.emission_maps import GENERIC_KINDS, family_symbols
from jaxmdp.blockmdp.linear_features import linear_value_features, n_linear_features
from tests.conftest import random_mdp

KEY = jax.random.key(0)

# (family, parameters, rows, cols, n_symbols) with rows x cols the rendering's size (benchmark.md §5).
FAMILIES = [
    ("RiverSwim", dict(size=5), 1, 5, 4),
    ("DeepSea", dict(size=4), 4, 4, 2),
    ("SimpleGrid", dict(size=4), 4, 4, 4),
    ("FrozenLake", dict(size=4, p_frozen=0.8), 4, 4, 4),
    ("MiniGridEmpty", dict(size=4), 4, 4, 6),
    ("MiniGridRooms", dict(room_size=2), 5, 5, 7),  # g = k rs + k - 1 = 2*2 + 1
    ("Taxi", dict(size=4, length=1, n_locations=3), 4, 4, 5),
    ("MiniGridDoorKey", dict(size=4), 4, 4, 10),
]


@functools.cache
def family_mdp(name: str, episodic: bool, seed: int = 0, **params) -> jaxmdp.MDP:
    return jaxmdp.make(name, episodic=episodic, seed=seed, **params)


def make(name, params, episodic):
    return family_mdp(name, episodic, **params)


def decoded_rendering(mdp, s):
    """The rendering of state ``s`` as symbol codes, decoded here from the text :func:`jaxmdp.render` prints."""
    symbols = family_symbols(mdp.info.family)
    return np.array([[symbols.index(c) for c in line] for line in jaxmdp.render(mdp, s).split("\n")], np.float32)


# The default profile: every family in one setting (continuous and episodic alternating), the other nightly.
@pytest.mark.parametrize("name, params, rows, cols, n_symbols, episodic", nightly_beyond(
    [(*f, episodic) for f in FAMILIES for episodic in (False, True)],
    lambda c: c[-1] == bool([f[0] for f in FAMILIES].index(c[0]) % 2),
    ids=lambda c: f"{c[0]}-{'episodic' if c[-1] else 'continuous'}"))
def test_shapes_and_values_of_every_family(name, params, rows, cols, n_symbols, episodic):
    m = make(name, params, episodic)
    S, F = m.n_states, len(m.info.node_fields)
    d = max(10, S // 10)
    expected = {
        "one_hot": (S,),
        "state_info": (F + episodic,),
        "image": (rows + episodic, cols),
        "tensor": (rows, cols, n_symbols + episodic),
        "linear_optimal": (d,),
        "linear_random": (d,),
    }
    lead = (m.H, S) if episodic else (S,)
    tables = {k: np.asarray(jaxmdp.emission_table(m, k, key=KEY)) for k in jaxmdp.EMISSION_KINDS}
    for kind, table in tables.items():
        assert table.shape == lead + expected[kind], kind
        assert table.dtype == np.float32

    fields = np.asarray(m.info.node_values, np.float32)
    images = np.stack([decoded_rendering(m, s) for s in range(S)])
    tensors = (images[..., None] == np.arange(n_symbols)).astype(np.float32)
    if not episodic:
        np.testing.assert_array_equal(tables["one_hot"], np.eye(S))
        np.testing.assert_array_equal(tables["state_info"], fields)
        np.testing.assert_array_equal(tables["image"], images)
        np.testing.assert_array_equal(tables["tensor"], tensors)
        return
    h = np.arange(m.H, dtype=np.float32)[:, None]
    # one_hot carries no time; state_info puts h first; image gets a top row of h; tensor a last channel of h.
    np.testing.assert_array_equal(tables["one_hot"], np.broadcast_to(np.eye(S), (m.H, S, S)))
    np.testing.assert_array_equal(tables["state_info"][..., 0], np.broadcast_to(h, (m.H, S)))
    np.testing.assert_array_equal(tables["state_info"][..., 1:], np.broadcast_to(fields, (m.H, S, F)))
    np.testing.assert_array_equal(tables["image"][:, :, 0, :], np.broadcast_to(h[..., None], (m.H, S, cols)))
    np.testing.assert_array_equal(tables["image"][:, :, 1:], np.broadcast_to(images, (m.H, *images.shape)))
    np.testing.assert_array_equal(tables["tensor"][..., -1], np.broadcast_to(h[..., None, None], (m.H, S, rows, cols)))
    np.testing.assert_array_equal(tables["tensor"][..., :-1], np.broadcast_to(tensors, (m.H, *tensors.shape)))


def test_deep_sea_start_state_info_of_the_spec():
    m = family_mdp("DeepSea", True, size=4)
    start = int(np.argmax(np.asarray(m.P0)))
    table = jaxmdp.emission_table(m, "state_info")
    np.testing.assert_array_equal(table[0, start], [0.0, 0.0, 3.0])
    np.testing.assert_array_equal(table[2, start], [2.0, 0.0, 3.0])


def test_deep_sea_example_of_the_paper():
    # Paper App. C, DeepSea emission table: size 6, agent in printed row 3, column 2; state information (2, 2).
    m = family_mdp("DeepSea", False, size=6)
    s = m.info.node_values.index((2, 2))
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "state_info")[s], [2.0, 2.0])
    image = np.ones((6, 6), np.float32)  # symbols ["A", " "]: blank = 1
    image[3, 2] = 0.0
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "image")[s], image)
    tensor = np.asarray(jaxmdp.emission_table(m, "tensor")[s])
    np.testing.assert_array_equal(tensor[..., 0], 1.0 - image)
    np.testing.assert_array_equal(tensor[..., 1], image)


def test_simple_grid_example_of_the_paper():
    # Paper App. C, SimpleGrid emission table: size 4, '+' top-left and bottom-right, '-' at the other corners (the
    # XOR reward type), agent at (3, 2) in printed row 1, column 3.
    m = family_mdp("SimpleGrid", False, size=4, reward_type="XOR")
    s = m.info.node_values.index((3, 2))
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "state_info")[s], [3.0, 2.0])
    # symbols [" ", "A", "+", "-"]
    expected = [[2, 0, 0, 3], [0, 0, 0, 1], [0, 0, 0, 0], [3, 0, 0, 2]]
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "image")[s], expected)


def test_river_swim_image():
    m = family_mdp("RiverSwim", True, size=5)
    table = jaxmdp.emission_table(m, "image")
    # symbols [" ", "A", "S", "G"]: S at 0, G at the end, A over the state (covering S at X = 0).
    np.testing.assert_array_equal(table[3, m.info.node_values.index((2,))], [[3, 3, 3, 3, 3], [2, 0, 1, 0, 3]])
    np.testing.assert_array_equal(table[0, m.info.node_values.index((0,))], [[0, 0, 0, 0, 0], [1, 0, 0, 0, 3]])


def test_frozen_lake_worked_example():
    # families.md §2.4: size 4, p_frozen 0.8, seed 0: board rows (lake[X]) SFFF / FFFH / HFFF / FHFG, printed with
    # row r = Y = 3 - r, column c = X, (0, 0) shown as F, the agent as A. Symbols ["A", "F", "H", "G"].
    m = family_mdp("FrozenLake", False, size=4, p_frozen=0.8, randomize_actions=False)
    expected = [[1, 2, 1, 3], [1, 1, 1, 1], [1, 1, 1, 2], [0, 1, 2, 1]]
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "image")[m.info.node_values.index((0, 0))], expected)
    s = m.info.node_values.index((1, 2))
    expected = [[1, 2, 1, 3], [1, 0, 1, 1], [1, 1, 1, 2], [1, 1, 2, 1]]
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "image")[s], expected)


def test_taxi_worked_example():
    # families.md §2.7: size 5 default, seed 0; walls (rows = X) 01010, 01010, 00000, 10101, 10101 printed with the
    # rows reversed; node (0, 4, -1, -1, 0, 4): taxi with the passenger on board at its destination.
    m = family_mdp("Taxi", False, size=5)
    node = (0, 4, -1, -1, 0, 4)
    s = m.info.node_values.index(node)
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "state_info")[s], node)
    # symbols [" ", "A", "X", "D", "P"]; the taxi covers the destination.
    expected = [[2, 0, 2, 0, 2], [2, 0, 2, 0, 2], [0, 0, 0, 0, 0], [0, 2, 0, 2, 0], [0, 2, 0, 2, 1]]
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "image")[s], expected)
    # A waiting passenger (P) and a destination (D) apart from the taxi.
    node = (2, 0, 0, 0, 4, 3)
    s = m.info.node_values.index(node)
    expected = [[2, 0, 2, 3, 2], [2, 0, 2, 0, 2], [1, 0, 0, 0, 0], [0, 2, 0, 2, 0], [4, 2, 0, 2, 0]]
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "image")[s], expected)


def test_minigrid_empty_worked_example_renders_the_queried_state():
    # families.md §2.5: size 4, seed 0, 2 starts: goal (3, 0), start (0, 2, LEFT). Symbols [" ", ">", "<", "v", "^",
    # "G"]. The reference drew the arrow at the MDP's current node ([quirk]); every state must look different here.
    m = family_mdp("MiniGridEmpty", True, size=4, n_starting_states=2, randomize_actions=False)
    s = m.info.node_values.index((0, 2, 3))
    image = np.asarray(jaxmdp.emission_table(m, "image"))
    np.testing.assert_array_equal(image[5, s], [[5] * 4, [0, 0, 0, 0], [2, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 5]])
    np.testing.assert_array_equal(jaxmdp.emission_table(m, "state_info")[5, s], [5, 0, 2, 3])
    assert len({im.tobytes() for im in image[0]}) == m.n_states


@pytest.mark.parametrize("name, params", [("MiniGridRooms", dict(room_size=2)), ("MiniGridDoorKey", dict(size=4))])
def test_minigrid_images_differ_between_states(name, params):
    for kind in ("image", "tensor"):
        table = np.asarray(jaxmdp.emission_table(family_mdp(name, False, **params), kind))
        assert len({row.tobytes() for row in table}) == table.shape[0]


# ---------------------------------------------------------------------------------------------------------------
# Linear maps
# ---------------------------------------------------------------------------------------------------------------


def numpy_values(mdp: jaxmdp.MDP, kind: str) -> np.ndarray:
    """V* (value iteration to convergence) or V^u (linear solve / backward induction) in float64: ``[S]``
    discounted (gamma 0.99) or ``[H + 1, S]`` finite-horizon."""
    T = np.asarray(mdp.T, np.float64)
    R = np.asarray(mdp.R, np.float64)
    S, A = R.shape
    if mdp.episodic:
        V = np.zeros((mdp.H + 1, S))
        for h in range(mdp.H - 1, -1, -1):
            Q = R + T @ V[h + 1]
            V[h] = Q.max(-1) if kind == "linear_optimal" else Q.mean(-1)
        return V
    if kind == "linear_random":
        return np.linalg.solve(np.eye(S) - 0.99 * T.mean(1), R.mean(1))
    V = np.zeros(S)
    for _ in range(20_000):
        V_new = (R + 0.99 * T @ V).max(-1)
        if np.max(np.abs(V_new - V)) < 1e-12:
            break
        V = V_new
    return V_new


def relative_residual(features: np.ndarray, v: np.ndarray) -> float:
    """``|v - Phi theta| / |v|`` of the float64 least-squares fit of ``v`` on the columns of ``Phi``."""
    Phi = np.asarray(features, np.float64).reshape(-1, features.shape[-1])
    v = np.asarray(v, np.float64).ravel()
    theta = np.linalg.lstsq(Phi, v, rcond=None)[0]
    return float(np.linalg.norm(Phi @ theta - v) / np.linalg.norm(v))


LINEAR_MDPS = [
    ("DeepSea 5 continuous", lambda: family_mdp("DeepSea", False, size=5)),  # S = 15 > d = 10
    ("random 40 continuous", lambda: random_mdp(np.random.default_rng(3), S=40, A=3)),
    ("SimpleGrid 4 episodic", lambda: family_mdp("SimpleGrid", True, size=4, p_rand=0.1)),
    ("RiverSwim 5 continuous (S < d)", lambda: family_mdp("RiverSwim", False, size=5)),
    ("random 130 episodic", lambda: random_mdp(np.random.default_rng(4), S=130, A=2, H=4)),  # d = 13
]


@pytest.mark.parametrize("kind", ["linear_optimal", "linear_random"])
@pytest.mark.parametrize("name, build", LINEAR_MDPS, ids=[n for n, _ in LINEAR_MDPS])
def test_value_lies_in_the_span_of_the_linear_features(name, build, kind):
    m = build()
    table = np.asarray(jaxmdp.emission_table(m, kind, key=KEY))
    d = n_linear_features(m.n_states)
    assert table.shape[-1] == d
    v = numpy_values(m, kind)[: m.H] if m.episodic else numpy_values(m, kind)
    rows = table.reshape(-1, d)
    norms = np.linalg.norm(rows, axis=0)
    if m.episodic:  # unit norm over h = 0 .. H; the terminal row H is dropped
        assert np.all(norms <= 1 + 1e-6)
    else:
        np.testing.assert_allclose(norms, 1.0, atol=1e-6)
    # V in the span to float32 precision ...
    assert relative_residual(table, v) < 2e-6
    # ... which is not true of an arbitrary vector when there are more rows than features.
    if rows.shape[0] > d:
        assert relative_residual(table, np.random.default_rng(0).standard_normal(rows.shape[0])) > 0.2


def test_linear_features_before_truncation_are_unit_norm_and_keep_the_first_column_direction():
    v = np.random.default_rng(1).standard_normal(50)
    F = linear_value_features(KEY, v, 10)
    np.testing.assert_allclose(np.linalg.norm(F, axis=0), 1.0, rtol=1e-12)
    assert relative_residual(F, v) < 1e-12
    assert relative_residual(F, np.ones(50)) < 1e-12  # the constant column of Psi is in the span too


def test_linear_features_of_a_constant_value_are_finite():
    # Zero rewards: V* = 0, so columns 0 and 1 of Psi are collinear (the reference's inverse would be singular).
    m = jaxmdp.custom_mdp(np.full((20, 2, 20), 1 / 20), R=np.zeros((20, 2)))
    table = np.asarray(jaxmdp.emission_table(m, "linear_optimal", key=KEY))
    assert np.all(np.isfinite(table)) and np.linalg.matrix_rank(table) == 10


def test_linear_maps_are_reproducible_from_the_key():
    m = family_mdp("DeepSea", False, size=5)
    a = jaxmdp.emission_table(m, "linear_optimal", key=jax.random.key(7))
    b = jaxmdp.emission_table(m, "linear_optimal", key=jax.random.key(7))
    c = jaxmdp.emission_table(m, "linear_optimal", key=jax.random.key(8))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


@pytest.mark.parametrize("kind", ["linear_optimal", "linear_random"])
def test_linear_maps_need_a_key(kind):
    with pytest.raises(ValueError, match=f"emission '{kind}' draws random features: pass key"):
        jaxmdp.emission_table(family_mdp("DeepSea", False, size=4), kind)


# ---------------------------------------------------------------------------------------------------------------
# Any MDP, padding, dtype, errors
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["state_info", "image", "tensor"])
def test_custom_and_stripped_mdps_reject_family_kinds(kind):
    custom = random_mdp(np.random.default_rng(0), S=5, A=2)
    stripped = family_mdp("DeepSea", False, size=4).strip()
    for m in (custom, stripped):
        with pytest.raises(ValueError, match=f"emission '{kind}' needs .*'one_hot', 'linear_optimal', 'linear_random'"):
            jaxmdp.emission_table(m, kind)
        for ok in GENERIC_KINDS:
            assert jaxmdp.emission_table(m, ok, key=KEY).shape[0] == m.n_states


def test_unknown_kind_lists_the_closest_names():
    m = family_mdp("DeepSea", False, size=4)
    with pytest.raises(ValueError, match="unknown emission 'onehot'; did you mean 'one_hot'"):
        jaxmdp.emission_table(m, "onehot")
    with pytest.raises(ValueError, match="did you mean 'state_info'"):
        jaxmdp.emission_table(m, "StateInfo")


def test_a_batch_is_rejected():
    batch = jaxmdp.stack([family_mdp("DeepSea", False, size=4)] * 2)
    with pytest.raises(ValueError, match="expects a single MDP"):
        jaxmdp.emission_table(batch, "one_hot")


@pytest.mark.parametrize("kind", jaxmdp.EMISSION_KINDS)
def test_padded_states_have_zero_rows(kind):
    m = family_mdp("DeepSea", True, size=4)
    padded = jaxmdp.pad(m, m.n_states + 3, m.n_actions, m.max_successors, m.H)
    table = np.asarray(jaxmdp.emission_table(padded, kind, key=KEY))
    assert table.shape[:2] == (m.H, m.n_states + 3)
    np.testing.assert_array_equal(table[:, m.n_states :], 0.0)
    if kind in ("state_info", "image", "tensor"):
        np.testing.assert_array_equal(table[:, : m.n_states], jaxmdp.emission_table(m, kind))


def test_the_mdp_dtype_is_kept():
    with jax.enable_x64(True):
        m = family_mdp("RiverSwim", False, size=12).astype(jnp.float64)
        for kind in jaxmdp.EMISSION_KINDS:
            assert jaxmdp.emission_table(m, kind, key=KEY).dtype == jnp.float64
