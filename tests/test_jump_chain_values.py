"""``dp.discounted_jump_chain_values``: the values of a chain with deterministic rows, by eliminating the jumping
states; ``dp.discounted_banded_jump_chain_values``: a banded chain whose missing row mass jumps to one state per row,
by a banded elimination and Woodbury's correction. Both against a float64 solve of the whole chain (numpy) and
hand-worked chains."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmdp import dynamic_programming as dp


def _chain(seed: int, S: int, jump_fraction: float, targets: int):
    """A random chain: a ``jump_fraction`` of the states move deterministically to one of ``targets`` random states,
    the others have random rows with a few successors."""
    rng = np.random.default_rng(seed)
    jumps = rng.random(S) < jump_fraction
    pool = rng.choice(S, size=targets, replace=False)
    jump = np.where(jumps, rng.choice(pool, size=S), -1)
    P = np.zeros((S, S), np.float32)
    for s in range(S):
        if jumps[s]:
            P[s, jump[s]] = 1.0
        else:
            succ = rng.choice(S, size=4, replace=False)
            P[s, succ] = rng.dirichlet(np.ones(4))
    r = rng.normal(size=S).astype(np.float32)
    return jnp.asarray(P), jnp.asarray(r), jnp.asarray(jump, jnp.int32)


def _float64_values(P, r, g):
    """``(I - g P)^{-1} r`` in float64 (numpy), the reference."""
    P, r = np.asarray(P, np.float64), np.asarray(r, np.float64)
    return np.linalg.solve(np.eye(P.shape[-1]) - g * P, r[..., None])[..., 0]


def _close(V, expected):
    """Float32 against float64: the elimination's error on these chains is at most 5.8e-7 max|V| (the dense float32
    solve's 5.6e-7), so ``5e-6 max|V|`` leaves a margin of 8 and stays far below the mutations' errors."""
    np.testing.assert_allclose(V, expected, rtol=0, atol=5e-6 * np.abs(expected).max())


def test_hand_worked_chain():
    """0 -> 1 -> 2 by jumps, 2 loops on itself through an ordinary row: V_2 = r_2 / (1 - g), V_1 = r_1 + g V_2,
    V_0 = r_0 + g V_1 (K = {1, 2}: the non-jumping state and the states jumped to)."""
    g = 0.5
    P = jnp.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    r = jnp.array([1.0, 2.0, 4.0])
    V, fits = dp.discounted_jump_chain_values(P, r, g, jnp.array([1, 2, -1]), size=2)
    assert bool(fits)
    np.testing.assert_allclose(V, [1.0 + 0.5 * 6.0, 2.0 + 0.5 * 8.0, 8.0], rtol=1e-6)
    assert not bool(dp.discounted_jump_chain_values(P, r, g, jnp.array([1, 2, -1]), size=1)[1])  # |K| = 2 > 1


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("jump_fraction,targets", [(1.0, 5), (0.9, 8), (0.5, 20), (0.0, 1)])
def test_against_the_dense_solve(seed, jump_fraction, targets):
    S, g = 60, 0.95
    P, r, jump = _chain(seed, S, jump_fraction, targets)
    j = np.asarray(jump)
    k = len(set(np.flatnonzero(j < 0)) | set(j[j >= 0]))  # |K|: the non-jumping states and the targets
    expected = _float64_values(P, r, g)
    for size in (k, k + 7):
        V, fits = jax.jit(dp.discounted_jump_chain_values, static_argnums=4)(P, r, g, jump, size)
        assert bool(fits)
        _close(V, expected)
    if k > 1:
        assert not bool(dp.discounted_jump_chain_values(P, r, g, jump, k - 1)[1])


def test_vmap_matches_one_chain_at_a_time():
    S, g = 40, 0.9
    chains = [_chain(seed, S, 0.8, 6) for seed in range(3)]
    P, r, jump = (jnp.stack(x) for x in zip(*chains))
    V, fits = jax.vmap(lambda p, rr, j: dp.discounted_jump_chain_values(p, rr, g, j, 24))(P, r, jump)
    assert bool(jnp.all(fits))
    _close(V, _float64_values(P, r, g))


def test_rows_given_by_a_function_are_read_at_the_eliminated_systems_states_only():
    # P as a function of the states whose rows are asked for: the same values, and only K's rows (then the clamped
    # index of the empty slots, whose rows are zeroed) are asked for.
    S, g = 60, 0.95
    P, r, jump = _chain(1, S, 0.9, 8)
    j = np.asarray(jump)
    K = set(np.flatnonzero(j < 0)) | set(j[j >= 0])
    asked = []

    def rows(s):
        asked.append(np.asarray(s))
        return P[s]

    V, fits = dp.discounted_jump_chain_values(rows, r, g, jump, len(K) + 3)
    assert bool(fits)
    _close(V, _float64_values(P, r, g))
    (states,) = asked
    assert set(states[: len(K)].tolist()) == K and set(states[len(K):].tolist()) == {S - 1}


def _banded_chain(seed: int, S: int, w: int, jump_fraction: float, targets: int):
    """A random banded part (rows with up to 3 successors within ``w`` positions, of random total mass below one; a
    ``jump_fraction`` of the rows empty) whose missing mass moves to one of ``targets`` random states, the target of
    some rows with a positive mass at a distance far beyond ``w``. Returns ``(B, deficit, target, r, P)`` with the
    whole chain ``P`` in float64."""
    rng = np.random.default_rng(seed)
    B = np.zeros((S, S), np.float32)
    for i in range(S):
        if rng.random() >= jump_fraction:
            near = np.arange(max(0, i - w), min(S, i + w + 1))
            sel = rng.choice(near, size=min(3, len(near)), replace=False)
            B[i, sel] = (rng.dirichlet(np.ones(len(sel))) * rng.uniform(0.2, 1.0)).astype(np.float32)
    B[rng.random(S) < 0.1, :] *= 0  # more empty rows
    deficit = (1.0 - B.astype(np.float64).sum(1)).astype(np.float32)
    target = rng.choice(rng.choice(S, size=targets, replace=False), size=S).astype(np.int32)
    P = B.astype(np.float64)
    P[np.arange(S), target] += deficit
    r = rng.normal(size=S).astype(np.float32)
    return jnp.asarray(B), jnp.asarray(deficit), jnp.asarray(target), jnp.asarray(r), P


def test_banded_jumps_hand_worked_chain():
    """Row 0 keeps 1/2 on itself and jumps with 1/2 to state 2; rows 1 and 2 are whole jumps to 2 and 0:
    ``V_0 = r_0 + g (V_0 + V_2) / 2``, ``V_2 = r_2 + g V_0``, ``V_1 = r_1 + g V_2``."""
    g = 0.5
    B = jnp.array([[0.5, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    r = jnp.array([1.0, 2.0, 4.0])
    deficit, target = jnp.array([0.5, 1.0, 1.0]), jnp.array([2, 2, 0])
    V, fits = dp.discounted_banded_jump_chain_values(B, deficit, target, r, g, 0, size=2)
    # V_0 (1 - g/2) = r_0 + g/2 (r_2 + g V_0)  =>  V_0 = (1 + 1) / (1 - 0.25 - 0.125) = 3.2
    V0 = 2.0 / 0.625
    assert bool(fits)
    np.testing.assert_allclose(V, [V0, 2.0 + 0.5 * (4.0 + 0.5 * V0), 4.0 + 0.5 * V0], rtol=1e-6)
    assert not bool(dp.discounted_banded_jump_chain_values(B, deficit, target, r, g, 0, size=1)[1])  # 2 targets


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("jump_fraction,targets", [(1.0, 5), (0.3, 12), (0.0, 30)])
def test_banded_jumps_against_the_dense_solve(seed, jump_fraction, targets):
    S, w, g = 80, 5, 0.99
    B, deficit, target, r, P = _banded_chain(seed, S, w, jump_fraction, targets)
    moving = np.asarray(deficit) > 0
    m = len(set(np.asarray(target)[moving]))
    expected = _float64_values(P, r, g)
    solve = jax.jit(dp.discounted_banded_jump_chain_values, static_argnums=(5, 6))
    for size in (m, m + 9):
        V, fits = solve(B, deficit, target, r, g, w, size)
        assert bool(fits)
        _close(V, expected)
    assert not bool(solve(B, deficit, target, r, g, w, m - 1)[1])


def test_banded_jumps_vmap_matches_one_chain_at_a_time():
    S, w, g = 50, 4, 0.95
    B, deficit, target, r, P = zip(*(_banded_chain(seed, S, w, 0.4, 7) for seed in range(3)))
    V, fits = jax.vmap(lambda *x: dp.discounted_banded_jump_chain_values(*x, g, w, 10))(
        *(jnp.stack(x) for x in (B, deficit, target, r)))
    assert bool(jnp.all(fits))
    _close(V, _float64_values(np.stack(P), jnp.stack(r), g))
