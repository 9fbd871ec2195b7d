"""The tuned near-optimal agent (hardness.analysis.near_optimal) and the search spaces it samples
(agents.search_spaces).

The search logic (objective = mean over tuning seeds, argmin per MDP, evaluation of the winner with the evaluation
seeds) runs against a fake runner whose regrets are a known function of the member, so every selection can be
checked by hand. One real run checks that an evaluated member's regret equals the same member run alone.
"""

from __future__ import annotations

import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import agents
import jaxmdp
from agents.search_spaces import SEARCH_SPACES, sample_candidates, search_space
from hardness.analysis import near_optimal
from jaxmdp.experiment import runner


def test_candidates_lie_in_the_reference_ranges_and_start_with_the_defaults():
    agent = agents.get("ucrl2")
    c = sample_candidates(agent, jax.random.key(3), 50)
    assert c.alpha_p.shape == (50,) and c.r_max.shape == (50,)
    for field, (low, high) in SEARCH_SPACES["ucrl2"].items():
        x = np.asarray(getattr(c, field))
        assert x[0] == getattr(agent.default_hparams, field)
        assert np.all((x[1:] >= low) & (x[1:] <= high)) and np.ptp(x[1:]) > 0.5 * (high - low)
    np.testing.assert_array_equal(c.r_max, 1.0)  # outside the space: the default
    again = sample_candidates(agent, jax.random.key(3), 50)
    np.testing.assert_array_equal(again.alpha_r, c.alpha_r)
    other = sample_candidates(agent, jax.random.key(4), 50, include_default=False)
    assert not np.allclose(other.alpha_r, c.alpha_r)


def test_every_search_space_names_fields_of_its_agent():
    for name, space in SEARCH_SPACES.items():
        default = agents.get(name).default_hparams
        for field, (low, high) in space.items():
            assert hasattr(default, field) and low < high
            agents.get(name).check_hparams(default.replace(**{field: low}))
            agents.get(name).check_hparams(default.replace(**{field: high}))


def test_search_space_errors():
    with pytest.raises(ValueError, match="random_episodic"):
        search_space("random_episodic")
    with pytest.raises(ValueError, match="n must be"):
        sample_candidates(agents.get("ucrl2"), jax.random.key(0), 0)


# ---------------------------------------------------------------------------------------------------------------
# Search logic against a fake runner
# ---------------------------------------------------------------------------------------------------------------


def fake_regret(mdp_index, alpha_p, seed):
    """Known final normalised regret of a member: best alpha_p is 1.0 for MDP 0 and 2.0 for MDP 1."""
    target = np.where(mdp_index == 0, 1.0, 2.0)
    return (alpha_p - target) ** 2 + 0.001 * (seed % 1000)


@pytest.fixture()
def fake_runner(monkeypatch):
    calls = []

    def run(agent, g, n_steps, **kwargs):
        calls.append(g)
        value = fake_regret(g.mdp_index, np.asarray(g.hparams.alpha_p), g.seeds)
        cols = {"normalized_cumulative_regret": value[None], "cumulative_regret": 10 * value[None]}
        return types.SimpleNamespace(column=cols.__getitem__, run_s=1.0, compile_s=2.0)

    monkeypatch.setattr(runner, "run", run)
    return calls


@pytest.fixture(scope="module")
def continuous_pair():
    base = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)
    return jax.vmap(jaxmdp.apply_p_rand, (None, 0))(base.strip(), jnp.array([0.0, 0.3]))


def test_search_picks_the_argmin_of_the_seed_mean_and_evaluates_it_with_the_eval_seeds(fake_runner, continuous_pair):
    res = near_optimal.tuned_regret(continuous_pair, [5, 7], n_steps=100, n_candidates=6, n_tuning_seeds=3)
    assert res.agent == "ucrl2"
    search, final = fake_runner
    cands = np.asarray(sample_candidates(agents.get("ucrl2"), jax.random.key(0), 6).alpha_p)
    # search grid: MDPs x candidates x tuning seeds, tuning seeds disjoint from evaluation seeds
    assert search.n_members == 2 * 6 * 3
    assert set(search.seeds) == {near_optimal.TUNING_SEED_OFFSET + j for j in range(3)}
    by_hand = np.asarray([[np.mean([fake_regret(np.asarray(m), a, near_optimal.TUNING_SEED_OFFSET + j)
                                    for j in range(3)]) for a in cands] for m in range(2)])
    np.testing.assert_allclose(res.search_scores, by_hand, rtol=1e-12)
    best = cands[np.argmin(by_hand, axis=1)]
    np.testing.assert_array_equal(res.best_hparams.alpha_p, best)
    # evaluation: one member per MDP, the winner's hyperparameters, the given seeds and their keys
    np.testing.assert_array_equal(final.mdp_index, [0, 1])
    np.testing.assert_array_equal(final.seeds, [5, 7])
    np.testing.assert_array_equal(final.hparams.alpha_p, best)
    np.testing.assert_array_equal(final.key_data[1], np.asarray(jax.random.key_data(jax.random.key(7))))
    np.testing.assert_allclose(res.normalized_cumulative_regret, fake_regret(np.arange(2), best, np.array([5, 7])))
    np.testing.assert_allclose(res.cumulative_regret, 10 * res.normalized_cumulative_regret)
    assert res.run_s == 2.0 and res.compile_s == 4.0


def test_one_candidate_runs_the_defaults_without_a_search(fake_runner, continuous_pair):
    res = near_optimal.tuned_regret(continuous_pair, [0, 1], n_steps=100, n_candidates=1)
    assert len(fake_runner) == 1 and res.search_scores.shape == (2, 0)
    np.testing.assert_array_equal(res.best_hparams.alpha_p, agents.get("ucrl2").default_hparams.alpha_p)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(eval_seeds=[0]), "eval_seeds"),
        (dict(eval_seeds=[0, near_optimal.TUNING_SEED_OFFSET]), "eval_seeds"),
        (dict(eval_seeds=[0, -1]), "eval_seeds"),
        (dict(n_steps=0), "n_steps"),
        (dict(n_candidates=0), "n_candidates"),
        (dict(n_tuning_seeds=True), "n_tuning_seeds"),
    ],
)
def test_bad_arguments_name_the_parameter(kwargs, name, continuous_pair):
    args = dict(eval_seeds=[0, 1])
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        near_optimal.tuned_regret(continuous_pair, **args)


def test_a_single_mdp_is_refused():
    with pytest.raises(ValueError, match="stacked batch"):
        near_optimal.tuned_regret(jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4), [0])


# ---------------------------------------------------------------------------------------------------------------
# A real run
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.nightly  # by default: test_benchmark_search.py's known best candidate
def test_real_episodic_run_equals_the_winner_run_by_hand():
    # DeepSea 5: PSRL still has regret after 300 steps (on DeepSea 3 and RiverSwim 3 it has none, and a comparison of
    # zeros would prove nothing).
    base = jaxmdp.make("DeepSea", episodic=True, seed=0, size=5, make_reward_stochastic=True)
    mdps = jax.vmap(jaxmdp.apply_p_rand, (None, 0))(base.strip(), jnp.array([0.0, 0.2]))
    # No search (one candidate: the defaults; the search logic is checked above): one compilation fewer.
    res = near_optimal.tuned_regret(mdps, [5, 7], n_steps=300, n_candidates=1)
    assert res.agent == "psrl_episodic" and res.search_scores.shape == (2, 0)
    agent = agents.get("psrl_episodic")
    for got, default in zip(jax.tree.leaves(res.best_hparams), jax.tree.leaves(agent.default_hparams)):
        np.testing.assert_array_equal(got, np.repeat(np.asarray(default)[None], 2, axis=0))
    # The evaluation members built by hand, in the other order (MDP 1 with seed 7 first): the same shapes, so the
    # runner reuses the compiled program; each member's regret depends only on its MDP, hyperparameters and key.
    hp = jax.tree.map(lambda x: x[::-1], res.best_hparams)
    keys = np.stack([np.asarray(jax.random.key_data(jax.random.key(s))) for s in (7, 5)])
    by_hand = runner.run(agent, runner.grid(mdps, hp, keys, mdp_index=[1, 0]), 300)
    np.testing.assert_allclose(by_hand.column("cumulative_regret")[-1], res.cumulative_regret[::-1], rtol=1e-6)
    np.testing.assert_allclose(by_hand.column("normalized_cumulative_regret")[-1],
                               res.normalized_cumulative_regret[::-1], rtol=1e-6)
    assert np.all(res.cumulative_regret > 1.0) and res.cumulative_regret[0] != res.cumulative_regret[1]
