"""jaxmdp.episodic: reachable pairs, T_epi, the reference's episodic-graph order and continuous form.

Independent checks: a numpy breadth-first construction of the reachable pairs, T_epi built entry by entry from its
definition (docs/families.md §1.8), the reference's stored episodic-graph node order, and RiverSwim's closed form
(``size (size + 1) / 2`` reachable pairs).
"""

import jax
import numpy as np
import pytest

import jaxmdp
from jaxmdp import episodic

from conftest import random_mdp, reference_index, shared_dir


def np_reachable(T, P0, H):
    S, A, _ = T.shape
    reach = np.zeros((H, S), bool)
    reach[0] = P0 > 0
    for h in range(1, H):
        reach[h] = (T[reach[h - 1]] > 0).any(axis=(0, 1))
    return reach


@pytest.fixture(scope="module")
def rand_episodic():
    rng = np.random.default_rng(3)
    return [random_mdp(rng, S=6, A=2, H=4, sparsity=0.2) for _ in range(3)]


def test_reachable_pairs_match_numpy_bfs(rand_episodic):
    for m in rand_episodic:
        np.testing.assert_array_equal(episodic.reachable_pairs(m), np_reachable(np.asarray(m.T), np.asarray(m.P0), 4))


@pytest.mark.parametrize("size", [2, 5, 10])
def test_river_swim_pair_count(size):
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=size, randomize_actions=False)
    assert int(np.sum(episodic.reachable_pairs(m))) == size * (size + 1) // 2
    assert len(episodic.episodic_graph_order(m)) == size * (size + 1) // 2


def test_time_augmented_kernel_definition(rand_episodic):
    m = rand_episodic[0]
    T, P0 = np.asarray(m.T), np.asarray(m.P0)
    H, (S, A, _) = 4, T.shape
    reach = np_reachable(T, P0, H)
    expected = np.zeros((H, S, A, S))
    for h in range(H):
        for s in range(S):
            if h == H - 1:
                expected[h, s] = P0
            elif reach[h, s]:
                expected[h, s] = T[s]
    np.testing.assert_allclose(episodic.time_augmented_kernel(m), expected, atol=1e-7)


def test_horizon_shorter_than_H_after_stacking(rand_episodic):
    short = random_mdp(np.random.default_rng(9), S=4, A=2, H=2, sparsity=0.3)
    batch = jaxmdp.stack([rand_episodic[0], short])
    reach = jax.vmap(episodic.reachable_pairs)(batch)
    np.testing.assert_array_equal(reach[1, :2, :4], np_reachable(np.asarray(short.T), np.asarray(short.P0), 2))
    assert not reach[1, 2:].any() and not reach[1, :, 4:].any()
    epi = jax.vmap(episodic.time_augmented_kernel)(batch)
    np.testing.assert_allclose(epi[1, 1, :4, :2, :4], np.broadcast_to(np.asarray(short.P0), (4, 2, 4)), atol=1e-7)
    assert float(np.abs(epi[1, 2:]).max()) == 0.0


def episodic_fixtures():
    entries = [e for e in reference_index() if e["setting"] == "episodic"]
    if not entries:
        return [pytest.param(None, marks=pytest.mark.skip(reason="../shared/reference is not available"))]
    return [pytest.param(e, id=e["id"]) for e in entries]


@pytest.mark.parametrize("entry", episodic_fixtures())
def test_graph_order_matches_reference(entry):
    """The depth-first order is the reference's whenever the successor order is (fixtures built from arrays carry no
    family order: exact for the families whose edge order is by index, and always for the first S pairs that the
    reset quirk uses when starts are given in the reference's order)."""
    with np.load(shared_dir() / "reference" / "colosseum" / entry["file"]) as z:
        T, R, P0, H = z["T"], z["R"], z["P0"], int(z["H"])
        ref, starts = z["episodic_graph_nodes"], z["starting_states"]
    m = jaxmdp.custom_mdp(T, R, P0, H=H)
    order = episodic.episodic_graph_order(m, starts=starts)
    assert {tuple(p) for p in order.tolist()} == {tuple(p) for p in ref.tolist()}
    np.testing.assert_array_equal(np.sort(order[:, 0] * 10_000 + order[:, 1]), np.sort(ref[:, 0] * 10_000 + ref[:, 1]))
    index_ordered = entry["family"] in ("RiverSwim", "DeepSea", "FrozenLake", "MiniGridRooms") or (
        entry["id"] in ("ref22_SimpleGrid_episodic", "ref28_MiniGridEmpty_episodic", "ref39_Taxi_episodic")
    )
    if index_ordered:
        np.testing.assert_array_equal(order, ref)


def test_continuous_form_rows_and_reset_quirk():
    T = np.zeros((3, 2, 3))
    T[0, 0, 1] = T[0, 1, 2] = 1.0
    T[1, :, 1] = 1.0
    T[2, :, 2] = 1.0
    P0 = np.array([0.5, 0.0, 0.5])  # two starts: 0 and 2
    m = jaxmdp.custom_mdp(T, np.arange(6.0).reshape(3, 2) / 10, P0, H=2)
    order = episodic.episodic_graph_order(m)
    # DFS: (0,0) -> (1,1) [reset children (0,0) seen, (0,2) new] -> (1,2); then (0,2) -> (1,2) seen.
    np.testing.assert_array_equal(order, [[0, 0], [1, 1], [0, 2], [1, 2]])
    cf = episodic.continuous_form(m)
    dense = np.zeros((4, 2, 4))
    np.add.at(dense, (np.arange(4)[:, None, None], np.arange(2)[None, :, None], np.asarray(cf.succ)), np.asarray(cf.succ_p))
    np.testing.assert_allclose(dense.sum(-1), 1.0, atol=1e-7)
    # Row (0, 0): action 0 -> (1, 1) = row 1, action 1 -> (1, 2) = row 3.
    np.testing.assert_allclose(dense[0], [[0, 1, 0, 0], [0, 0, 0, 1]], atol=1e-7)
    # Reset rows (1, 1) and (1, 2): the quirk puts start 2's mass on row 2 -- here that is (0, 2) by luck of order --
    # and start 0's mass on row 0.
    np.testing.assert_allclose(dense[1], [[0.5, 0, 0.5, 0]] * 2, atol=1e-7)
    np.testing.assert_allclose(np.asarray(cf.R), np.asarray(m.R)[[0, 1, 2, 2]], atol=1e-7)


def test_reset_quirk_lands_on_graph_index_not_on_pair():
    # Starts 0 and 1; DFS puts (1, 2) at row 1, so the quirk sends start 1's reset mass there.
    T = np.zeros((3, 1, 3))
    T[0, 0, 2] = 1.0
    T[1, 0, 2] = 1.0
    T[2, 0, 2] = 1.0
    m = jaxmdp.custom_mdp(T, np.zeros((3, 1)), np.array([0.5, 0.5, 0.0]), H=2)
    order = episodic.episodic_graph_order(m)
    np.testing.assert_array_equal(order, [[0, 0], [1, 2], [0, 1]])
    quirk = episodic.continuous_form(m)
    fixed = episodic.continuous_form(m, reset_quirk=False)
    assert sorted(np.asarray(quirk.succ)[1, 0, :2].tolist()) == [0, 1]
    assert sorted(np.asarray(fixed.succ)[1, 0, :2].tolist()) == [0, 2]


def test_recorded_successor_order_is_used_by_family_mdps():
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4, p_lazy=0.1, p_rand=0.1, randomize_actions=False)
    assert m.info.layout_value("start_order") == (0,)
    # X = 1: base action LEFT lists X=0, the lazy self-loop X=1, then RIGHT's X=2 (docs/families.md §1.3).
    assert episodic.graph_successors(m)[1] == [0, 1, 2]
    relabelled = jaxmdp.permute_states(m, [3, 2, 1, 0])
    assert episodic.graph_successors(relabelled)[2] == [1, 2, 3]  # stale metadata is ignored
