"""The diameter against independent computations.

* paper, continuous: brute force over every deterministic stationary policy with numpy float64 hitting-time solves;
  closed forms (deterministic chains: graph diameter; DeepSea of size n: 2n - 2);
* paper, episodic: the same brute force on the explicitly built time-augmented MDP;
* colosseum: the reference's stored values (tests/test_hardness_reference.py) and its worked examples here;
* documented answers: not strongly connected -> inf (converged), budget exhausted -> inf (not converged).
"""

import dataclasses

import jax
import numpy as np
import pytest

import hardness
import jaxmdp

from conftest import compilations, random_mdp
from hardness_helpers import brute_force_diameter, deep_sea, time_augmented


def dense_random(rng, S, A, sparsity=0.5):
    T = rng.random((S, A, S)) * (rng.random((S, A, S)) < sparsity)
    T[np.arange(S), :, (np.arange(S) + 1) % S] += 0.2  # a cycle keeps every state reachable
    return T / T.sum(-1, keepdims=True)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_continuous_paper_equals_brute_force(seed):
    rng = np.random.default_rng(seed)
    T = dense_random(rng, 5, 2 + seed % 2)
    m = jaxmdp.custom_mdp(T, np.zeros(T.shape[:2]))
    res = hardness.diameter(m)
    assert bool(res.converged) and bool(res.finite)
    np.testing.assert_allclose(float(res.value), brute_force_diameter(T), rtol=2e-6)


def test_continuous_phase_two_path():
    # More states than candidates, so the second phase (restricted targets) decides.
    rng = np.random.default_rng(7)
    T = dense_random(rng, 7, 2, sparsity=0.3)
    m = jaxmdp.custom_mdp(T, np.zeros((7, 2)))
    res = hardness.diameter(m, n_candidates=2)
    np.testing.assert_allclose(float(res.value), brute_force_diameter(T), rtol=2e-6)
    np.testing.assert_allclose(float(hardness.diameter(m, n_candidates=7).value), float(res.value), rtol=2e-6)


@pytest.mark.parametrize("size", [2, 5, 12])
def test_deterministic_chain_is_graph_diameter(size):
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=size, randomize_actions=False)
    for variant in ("paper", "colosseum"):
        assert float(hardness.diameter(m, variant=variant).value) == size - 1


def test_directed_cycle():
    S = 6
    T = np.zeros((S, 1, S))
    T[np.arange(S), 0, (np.arange(S) + 1) % S] = 1.0
    m = jaxmdp.custom_mdp(T, np.zeros((S, 1)))
    assert float(hardness.diameter(m).value) == S - 1


@pytest.mark.parametrize("n", [4, 10])
def test_deep_sea_closed_form(n):
    m = deep_sea(n)
    assert float(hardness.diameter(m).value) == 2 * n - 2
    assert float(hardness.diameter(m, variant="colosseum").value) == 2 * n - 2


def test_river_swim_worked_example():
    # docs/families.md §2.1: size 5, p_lazy 0.1, p_rand 0.2 -> diameter 5.3816 (the reference, eps = 1e-3).
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, p_lazy=0.1, p_rand=0.2, randomize_actions=False)
    np.testing.assert_allclose(float(hardness.diameter(m, variant="colosseum").value), 5.3816, atol=1e-4)
    T = np.asarray(m.T, np.float64)
    np.testing.assert_allclose(float(hardness.diameter(m).value), brute_force_diameter(T), rtol=2e-6)


def test_not_strongly_connected_is_certified_infinite():
    T = np.zeros((3, 2, 3))
    T[0, 0, 1] = T[0, 1, 0] = 1.0
    T[1, :, 2] = 1.0
    T[2, :, 2] = 1.0  # absorbing: nothing comes back
    m = jaxmdp.custom_mdp(T, np.zeros((3, 2)))
    assert not bool(hardness.strongly_connected(m))
    for variant in ("paper", "colosseum"):
        res = hardness.diameter(m, variant=variant)
        assert float(res.value) == np.inf and bool(res.converged) and not bool(res.finite)


def test_eager_calls_compile_once_per_shape(caplog):
    """The measures' entry points compile once per shape, whatever the MDP's labels (each strips them before its
    jitted core; ``strongly_connected`` through ``dynamic_programming.compiled``)."""
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5)
    other = m.replace(info=dataclasses.replace(m.info, node_labels=tuple(f"other {i}" for i in range(5))))

    def calls(mdp):
        return [lambda: hardness.strongly_connected(mdp), lambda: hardness.measures(mdp),
                lambda: hardness.diameter(mdp, variant="colosseum")]

    assert compilations(caplog, calls(m))
    assert compilations(caplog, calls(other)) == []


def test_slow_convergence_exhausts_budget_explicitly():
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=6, p_lazy=0.999, randomize_actions=False)
    res = hardness.diameter(m, max_iter=200)
    assert float(res.value) == np.inf and not bool(res.converged)
    # With enough sweeps it is exact: time dilation by 1 / (1 - p_lazy).
    full = hardness.diameter(m, max_iter=2_000_000, rtol=1e-4)
    assert bool(full.converged)
    np.testing.assert_allclose(float(full.value), 5 / (1 - 0.999), rtol=2e-4)


@pytest.mark.parametrize("seed", [0, 1])
def test_episodic_paper_equals_time_augmented_brute_force(seed):
    rng = np.random.default_rng(10 + seed)
    m = random_mdp(rng, S=3, A=2, H=3, sparsity=0.3)
    T, R, P0 = (np.asarray(x, np.float64) for x in (m.T, m.R, m.P0))
    Ta, _, pairs = time_augmented(T, R, P0, 3)
    assert len(pairs) <= 9
    res = hardness.diameter(m)
    assert bool(res.converged)
    np.testing.assert_allclose(float(res.value), brute_force_diameter(Ta), rtol=2e-6)


def test_episodic_paper_deterministic_river_swim():
    # Deterministic RiverSwim, H = size: the worst trip is from (0, 0) to (0, 1)... every value is an integer; the
    # brute force on the augmented MDP confirms the number.
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4, randomize_actions=False)
    T, R, P0 = (np.asarray(x, np.float64) for x in (m.T, m.R, m.P0))
    Ta, _, _ = time_augmented(T, R, P0, 4)
    value = float(hardness.diameter(m).value)
    assert value == brute_force_diameter(Ta) == round(value)


def test_colosseum_episodic_worked_example():
    # docs/measures.md §3.2: RiverSwim episodic size 40, deterministic -> 40.0; DeepSea-like chains give H.
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=40, randomize_actions=False)
    assert float(hardness.diameter(m, variant="colosseum").value) == 40.0


def test_bad_arguments():
    m = deep_sea(3)
    with pytest.raises(ValueError, match="variant"):
        hardness.diameter(m, variant="exact")
    with pytest.raises(ValueError, match="rtol"):
        hardness.diameter(m, rtol=0.0)


def test_colosseum_episodic_never_reached_state_is_infinite():
    # State 2 is reachable, but not within an episode of length 2 from state 0: the reference's sweep would never
    # stop on it; the hitting time is infinite.
    T = np.zeros((3, 1, 3))
    T[0, 0, 1] = T[1, 0, 2] = T[2, 0, 0] = 1.0
    m = jaxmdp.custom_mdp(T, np.zeros((3, 1)), H=2)
    res = hardness.diameter(m, variant="colosseum")
    assert float(res.value) == np.inf and bool(res.converged)
    # The paper's time-augmented MDP only has the reachable pairs (0, 0) and (1, 1): diameter 1.
    assert float(hardness.diameter(m).value) == 1.0


def np_sparse_reference(T):
    """docs/measures.md §3.1, the reference's solver above 1000 states, written sequentially (targets in index
    order)."""
    S = T.shape[0]
    D = -np.inf
    for e in range(S):
        ET = np.zeros(S)
        keep = np.arange(S) != e
        while True:
            Z = np.where(keep, ET, 0.0)
            new = np.where(keep, np.min(1.0 + T @ Z, axis=1), 0.0)
            diff = np.max(np.abs(new - ET))
            ET = new
            if diff < 1e-3 or (diff < 0.05 and ET.max() - 1 < D):
                break
        D = max(D, ET.max())
    return max(0.0, D)


def test_colosseum_sparse_path_replays_the_sequential_early_exit():
    from hardness.diameter import _continuous_colosseum_sparse

    for seed in range(3):
        rng = np.random.default_rng(40 + seed)
        T = dense_random(rng, 8, 2, sparsity=0.3)
        T = 0.6 * T + 0.4 * np.eye(8)[:, None, :]  # laziness: slow enough that the early exit matters
        m = jaxmdp.custom_mdp(T.astype(np.float32), np.zeros((8, 2)))
        got = jax.jit(lambda m: _continuous_colosseum_sparse(m, hardness.strongly_connected(m), 100_000))(m)
        np.testing.assert_allclose(float(got.value), np_sparse_reference(np.asarray(m.T, np.float64)), rtol=1e-5)
