"""Construction order of the action permutations (families.md §1.4, §1.6; refined in construction.py)."""

import numpy as np

import jaxmdp


def _action0_moves_right(m: jaxmdp.MDP) -> list[int]:
    # RiverSwim state X = index; agent action 0 runs base RIGHT iff it puts more mass on X + 1 than action 1.
    T = np.asarray(m.T)
    return [int(T[x, 0, x + 1] > T[x, 1, x + 1]) for x in range(m.n_states - 1)]


def test_point_mass_rewards_draw_permutations_in_preorder():
    # With point-mass rewards every node's permutation is drawn when it is first processed: RiverSwim visits
    # X = 0, 1, ... in order, so sigma_X = argsort of row X of RandomState(seed).rand(S, 2).
    m = jaxmdp.make("RiverSwim", episodic=False, seed=2, size=50, p_rand=0.2, p_lazy=0.1)
    u = np.random.RandomState(2).rand(50, 2)
    expected = [int(u[x, 0] > u[x, 1]) for x in range(49)]  # sigma = [1, 0]: agent 0 runs base RIGHT
    assert _action0_moves_right(m) == expected


def test_stochastic_rewards_draw_permutations_after_the_first_subtree():
    # ref02 (seed 2, size 50, p_rand .2, p_lazy .1, stochastic): the reference's pattern, read off its T.
    ref02 = [1, 0, 0, 0, 1, 1, 1, 0, 1, 1, 1, 1, 1, 1, 0, 1, 1, 1, 0, 1, 1, 1, 1, 1, 0, 1, 0, 0, 1, 1, 1, 0, 1, 1, 1,
             1, 0, 1, 0, 1, 1, 1, 1, 0, 0, 1, 1, 0, 1, 1]
    m = jaxmdp.make(
        "RiverSwim", episodic=False, seed=2, size=50, p_rand=0.2, p_lazy=0.1, make_reward_stochastic=True
    )
    assert _action0_moves_right(m) == ref02[:49]
    # Independent account: X = 0 draws first (its first reward lookup turns the "all deterministic" flag off).
    # The LEFT list of X holds X + 1 (the p_rand outcome), so the recursion walks down the whole chain inside
    # base action 0 and the nodes finish their LEFT subtree in reverse: X = 49 draws second, ..., X = 1 last.
    u = np.random.RandomState(2).rand(50, 2)
    order = [0] + list(range(49, 0, -1))
    expected = {x: int(u[i, 0] > u[i, 1]) for i, x in enumerate(order)}
    assert _action0_moves_right(m) == [expected[x] for x in range(49)]
