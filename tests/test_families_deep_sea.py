"""DeepSea (docs/families.md §2.2): structure, rewards, horizon, validation and rendering, against the spec's
examples."""

import numpy as np
import pytest

import jaxmdp


def _make(episodic=False, **kw):
    kw.setdefault("randomize_actions", False)
    return jaxmdp.make("DeepSea", episodic=episodic, seed=kw.pop("seed", 0), **kw)


def _idx(m, x, y):
    return m.info.node_labels.index(f"X={x},Y={y}")


LEFT, RIGHT = 0, 1


@pytest.mark.parametrize("size,S", [(2, 3), (3, 6), (5, 15), (10, 55), (20, 210)])
def test_state_counts_are_the_reachable_triangle(size, S):
    m = _make(size=size)
    assert m.n_states == S == size * (size + 1) // 2
    # Row Y = size-1-t holds exactly X = 0..t.
    cells = {tuple(v) for v in m.info.node_values}
    assert cells == {(x, size - 1 - t) for t in range(size) for x in range(t + 1)}


def test_discovery_order_tries_left_first():
    m = _make(size=4)
    assert m.info.node_labels == tuple(
        f"X={x},Y={y}" for x, y in [(0, 3), (0, 2), (0, 1), (0, 0), (1, 0), (1, 1), (2, 0), (1, 2), (2, 1), (3, 0)]
    )
    assert m.info.node_fields == ("X", "Y")
    np.testing.assert_array_equal(m.P0, np.eye(10)[0])


def test_worked_example_rows_size_4_deterministic():
    m = _make(size=4)
    T, R = np.asarray(m.T), np.asarray(m.R)
    s = _idx(m, 0, 3)
    np.testing.assert_array_equal(T[s, LEFT], np.eye(10)[_idx(m, 0, 2)])
    np.testing.assert_array_equal(T[s, RIGHT], np.eye(10)[_idx(m, 1, 2)])
    assert R[s, LEFT] == pytest.approx(1 / 16, abs=1e-7) and R[s, RIGHT] == 0.0
    # The bottom row jumps back to the top; LEFT still pays 1/size^2, RIGHT pays 1 only at the bottom-right corner.
    for x in range(4):
        b = _idx(m, x, 0)
        np.testing.assert_array_equal(T[b], np.tile(np.eye(10)[0], (2, 1)))
        assert R[b, LEFT] == pytest.approx(1 / 16, abs=1e-7)
        assert R[b, RIGHT] == (1.0 if x == 3 else 0.0)
    # Clipping at the right border: (2,1) RIGHT -> (3,0); in the middle LEFT/RIGHT move diagonally.
    np.testing.assert_array_equal(T[_idx(m, 2, 1), RIGHT], np.eye(10)[_idx(m, 3, 0)])
    np.testing.assert_array_equal(T[_idx(m, 1, 1), LEFT], np.eye(10)[_idx(m, 0, 0)])


def test_p_rand_mixes_the_other_action_and_rewards_follow_the_chosen_action():
    m = _make(size=4, p_rand=0.1)
    T, R = np.asarray(m.T), np.asarray(m.R)
    s = _idx(m, 0, 3)
    # Own move with (1 - 0.1) + 0.1 / 2 = 0.95, the other action's move with 0.1 / 2 = 0.05.
    left, right = np.zeros(10), np.zeros(10)
    left[_idx(m, 0, 2)], left[_idx(m, 1, 2)] = 0.95, 0.05
    right[_idx(m, 1, 2)], right[_idx(m, 0, 2)] = 0.95, 0.05
    np.testing.assert_allclose(T[s, LEFT], left, atol=1e-7)
    np.testing.assert_allclose(T[s, RIGHT], right, atol=1e-7)
    assert R[s, LEFT] == pytest.approx(1 / 16, abs=1e-7) and R[s, RIGHT] == 0.0
    # Bottom-right RIGHT: both outcomes go to the top and are rewarded as RIGHT at the corner.
    assert R[_idx(m, 3, 0), RIGHT] == pytest.approx(1.0)


@pytest.mark.parametrize(
    "size,v,opt,sub,other",
    [(4, 1.0, (3, 1), (1, 7), (1, 70)), (13, 1.0, (12, 1), (1, 25), (1, 250)), (4, 2.0, (6, 2), (2, 14), (2, 140))],
)
def test_stochastic_default_distributions(size, v, opt, sub, other):
    m = _make(size=size, make_reward_stochastic=True, reward_variance_multiplier=v)
    mean, conc = np.asarray(m.reward_mean), np.asarray(m.reward_conc)
    top, nxt_l, nxt_r = _idx(m, 0, size - 1), _idx(m, 0, size - 2), _idx(m, 1, size - 2)
    corner = _idx(m, size - 1, 0)
    for (s, a, t), (alpha, beta) in {
        (top, LEFT, nxt_l): sub,
        (top, RIGHT, nxt_r): other,
        (corner, RIGHT, top): opt,
        (corner, LEFT, top): sub,
    }.items():
        assert conc[s, a, t] == pytest.approx(alpha + beta, rel=1e-6)
        assert mean[s, a, t] == pytest.approx(alpha / (alpha + beta), rel=1e-6)
    assert dict(m.info.params)["optimal_distribution"] == f"Beta({opt[0]:g}, {opt[1]:g})"


def test_deterministic_defaults_and_parameter_order():
    m = _make(size=5, seed=3)
    assert m.info.params == (
        ("seed", 3),
        ("randomize_actions", False),
        ("p_lazy", None),
        ("p_rand", None),
        ("make_reward_stochastic", False),
        ("reward_variance_multiplier", 1.0),
        ("size", 5),
        ("optimal_return", 1.0),
        ("suboptimal_return", 0.5),
        ("optimal_distribution", "Deterministic(1)"),
        ("sub_optimal_distribution", "Deterministic(0.04)"),
        ("other_distribution", "Deterministic(0)"),
    )
    assert np.all(np.asarray(m.reward_conc) == 0)


def test_explicit_distributions_replace_the_defaults():
    m = _make(
        size=3,
        optimal_distribution=("deterministic", (0.7,)),
        sub_optimal_distribution=("deterministic", (0.2,)),
        other_distribution=("deterministic", (0.1,)),
    )
    R = np.asarray(m.R)
    assert R[0, LEFT] == pytest.approx(0.2) and R[0, RIGHT] == pytest.approx(0.1)
    assert R[_idx(m, 2, 0), RIGHT] == pytest.approx(0.7)


def test_episodic_horizon_is_fixed_to_size():
    for size in (2, 5, 8):
        m = _make(episodic=True, size=size)
        assert m.H == size and int(m.horizon) == size
    assert _make(size=5).H is None
    with pytest.raises(ValueError, match="H must not be given"):
        _make(episodic=True, size=5, H=5)


def test_validation_errors():
    with pytest.raises(ValueError, match="size must be an integer >= 2"):
        _make(size=1)
    with pytest.raises(ValueError, match="size must be an integer >= 2"):
        _make(size=3.0)
    with pytest.raises(ValueError, match="p_lazy must be None for DeepSea"):
        _make(size=4, p_lazy=0.1)
    assert _make(size=4, p_lazy=0.0).n_states == 10  # 0 means "no lazy mechanic", as in the reference
    with pytest.raises(ValueError, match="optimal_return - 0.1 must exceed suboptimal_return"):
        _make(size=4, suboptimal_return=0.95)
    with pytest.raises(ValueError, match=r"optimal_return must lie in \(0, size=4\)"):
        _make(size=4, make_reward_stochastic=True, optimal_return=4.0, suboptimal_return=0.5)
    with pytest.raises(ValueError, match="all or none"):
        _make(size=4, optimal_distribution=("deterministic", (1.0,)))
    with pytest.raises(ValueError, match="make_reward_stochastic=False"):
        _make(size=4, optimal_distribution=("beta", (2, 1)), sub_optimal_distribution=("beta", (1, 2)),
              other_distribution=("beta", (1, 9)))
    with pytest.raises(ValueError, match="p_rand must lie in"):
        _make(size=4, p_rand=1.0)


def test_randomized_actions_relabel_per_state_and_keep_the_dynamics():
    base = _make(size=6, p_rand=0.2)
    m = _make(size=6, p_rand=0.2, randomize_actions=True, seed=11)
    T0, T1, R0, R1 = (np.asarray(x) for x in (base.T, m.T, base.R, m.R))
    assert base.info.node_labels == m.info.node_labels
    flipped = 0
    for s in range(m.n_states):
        perm = [0, 1] if np.allclose(T1[s], T0[s]) and np.allclose(R1[s], R0[s]) else [1, 0]
        np.testing.assert_allclose(T1[s], T0[s, perm], atol=1e-7)
        np.testing.assert_allclose(R1[s], R0[s, perm], atol=1e-7)
        flipped += perm == [1, 0]
    assert 0 < flipped < m.n_states


def test_rendering():
    m = _make(size=3)
    assert jaxmdp.render(m, _idx(m, 0, 2)) == "A  \n   \n   "
    assert jaxmdp.render(m, _idx(m, 1, 1)) == "   \n A \n   "
    assert jaxmdp.render(m, _idx(m, 2, 0)) == "   \n   \n  A"
    e = _make(episodic=True, size=3)
    assert jaxmdp.render(e, _idx(e, 1, 1), h=2).split("\n") == ["H=2", "___", "   ", " A ", "   "]
    e2 = _make(episodic=True, size=2)
    assert jaxmdp.render(e2, 0, h=1).split("\n") == ["H=1", "___", "A X", "  X"]
