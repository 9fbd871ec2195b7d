"""Construction (construction.py): the order of the action permutations (docs/families.md §1.4, §1.6) and the horizon's
eccentricity search (§1.8)."""

import numpy as np
import pytest

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


def test_eccentricity_of_many_sources_matches_one_search_per_source():
    from collections import deque

    from jaxmdp.mdp_families.construction import _eccentricity

    rng = np.random.RandomState(0)
    for trial in range(20):
        n = int(rng.randint(2, 40))
        succ = {i: [int(j) for j in rng.choice(n, size=rng.randint(0, 4))] for i in range(n)}
        sources = [int(s) for s in rng.choice(n, size=rng.randint(1, 6))]  # duplicates allowed
        best = 0
        for src in sources:
            dist, queue = {src: 0}, deque([src])
            while queue:
                a = queue.popleft()
                for b in succ[a]:
                    if b not in dist:
                        dist[b] = dist[a] + 1
                        queue.append(b)
            best = max(best, max(dist.values()))
        assert _eccentricity(succ.__getitem__, sources) == best, trial


def test_a_family_with_a_formula_horizon_skips_the_eccentricity_search(monkeypatch):
    from jaxmdp.mdp_families import construction

    def fail(*args):
        raise AssertionError("the eccentricity search ran")

    monkeypatch.setattr(construction, "_eccentricity", fail)
    assert jaxmdp.make("Taxi", episodic=True, seed=0, size=4, length=1, n_locations=3).H == 24
    with pytest.raises(AssertionError, match="search ran"):
        jaxmdp.make("RiverSwim", episodic=True, seed=0, size=3)


def test_a_builder_declaring_other_common_defaults_is_refused():
    # The common defaults live in COMMON_DEFAULTS; a family whose public signature drifts from them fails at import.
    from jaxmdp.mdp_families import construction
    from jaxmdp.mdp_families.river_swim import RiverSwimFamily

    def declaration(*, episodic, seed, size, p_rand=None, p_lazy=None, randomize_actions=False,
                    make_reward_stochastic=False, reward_variance_multiplier=1.0, H=None):
        """A RiverSwim whose randomize_actions defaults to False."""

    with pytest.raises(TypeError, match="randomize_actions"):
        construction.family_builder(RiverSwimFamily)(declaration)


def test_a_builder_not_declaring_a_reward_parameter_is_refused():
    # The family's RewardParameters names the reward parameters; the builder's declaration must hold every one of them.
    from jaxmdp.mdp_families import construction
    from jaxmdp.mdp_families.river_swim import RiverSwimFamily

    def declaration(*, episodic, seed, size, p_rand=None, p_lazy=None, randomize_actions=True,
                    make_reward_stochastic=False, reward_variance_multiplier=1.0, optimal_mean_reward=0.9,
                    sub_optimal_mean_reward=0.2, H=None):
        """A RiverSwim without its distribution parameters."""

    with pytest.raises(TypeError, match="other_distribution"):
        construction.family_builder(RiverSwimFamily)(declaration)
