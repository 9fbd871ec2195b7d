"""The benchmark's random search (App. F; benchmark.md §7, agents.md §8): reference-style candidates, batched
evaluation with a known best candidate, selection and the tuned file's provenance."""

import json
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct

import jaxmdp
from hardness.benchmark import hparams, search
from jaxmdp.agent_interface import Agent


def test_reference_candidates_use_seeds_sigma_plus_i_and_four_decimals():
    space = {"c_1": (0.001, 1.1), "c_2": (0.001, 1.1), "min_at": (0.001, 0.2)}
    got = hparams.reference_candidates("q_learning_episodic", 3, seed=42)
    for i, cand in enumerate(got):
        rng = np.random.RandomState(42 + i)  # the reference seeds numpy's generator with sigma + i
        expected = {f: round(rng.uniform(lo, hi), 4) for f, (lo, hi) in space.items()}
        assert cand == expected
        assert list(cand) == list(space)  # drawn in the space's order
    assert hparams.reference_candidates("q_learning_episodic", 1, seed=43)[0] == got[1]


class EpsHParams(struct.PyTreeNode):
    eps: float | jax.Array = 0.5


class EpsState(struct.PyTreeNode):
    eps: jax.Array
    action_mask: jax.Array
    n_states: int = struct.field(pytree_node=False)


def _policy(state):
    """Action 0 with probability ``1 - eps``, else uniform over the valid actions."""
    w = state.action_mask / jnp.sum(state.action_mask)
    row = state.eps * w + (1 - state.eps) * (jnp.arange(w.shape[0]) == 0)
    return jnp.broadcast_to(row, (state.n_states, w.shape[0]))


def _act(key, state, obs, h):
    return jax.random.choice(key, state.action_mask.shape[0], p=_policy(state)[0]).astype(jnp.int32)


EPS_AGENT = Agent(
    name="eps_greedy_toy", episodic=False, default_hparams=EpsHParams(),
    init=lambda key, spec, hp: EpsState(eps=jnp.asarray(hp.eps, jnp.float32), action_mask=spec.action_mask,
                                        n_states=spec.n_states),
    act=_act, update=lambda state, tr: state, policy=_policy,
)


def _pays_for_action_0(S: int) -> jaxmdp.MDP:
    """Every state pays 1 for action 0 and 0 for action 1; uniform transitions. Gains: optimal 1, worst 0."""
    T = np.full((S, 2, S), 1.0 / S)
    mean = np.zeros((S, 2, S))
    mean[:, 0] = 1.0
    return jaxmdp.custom_mdp(T, P0=np.full(S, 1.0 / S), reward_mean=mean)


def test_search_finds_the_known_best_candidate_across_buckets():
    # The normalised regret per step of eps is exactly eps / 2 on both MDPs, so the final normalised cumulative
    # regret is n_steps * eps / 2 and the smallest eps wins.
    values = hparams.reference_candidates(EPS_AGENT, 5, seed=3, space={"eps": (0.0, 1.0)})
    candidates = [EPS_AGENT.default_hparams.replace(eps=v["eps"]) for v in values]
    mdps = [_pays_for_action_0(1), _pays_for_action_0(1), _pays_for_action_0(4)]
    n = 400
    scores, run_s, _ = search.evaluate(EPS_AGENT, candidates, mdps, [0, 1, 0], n, log_period=50, n_buckets=2)
    eps = np.array([v["eps"] for v in values])
    np.testing.assert_allclose(scores, np.broadcast_to(n * eps[:, None] / 2, (5, 3)), rtol=1e-5)
    assert search.select(scores) == int(np.argmin(eps))
    assert run_s > 0


def test_a_search_in_a_log_shows_each_bucket_s_progress_in_lines(capfd):
    """With ``progress`` and stderr not a terminal (pytest's capture, as a tune run's log), each bucket's runner
    display writes plain lines (its compilations, a last line at 100 %) after the bucket's own line; without
    ``progress`` nothing is written."""
    mdps = [_pays_for_action_0(1), _pays_for_action_0(4)]
    candidates = [EPS_AGENT.default_hparams.replace(eps=e) for e in (0.1, 0.9)]
    search.evaluate(EPS_AGENT, candidates, mdps, [0, 0], 200, log_period=50, n_buckets=2, progress=True)
    err = capfd.readouterr().err
    assert "\r" not in err
    for b, states in ((1, 1), (2, 4)):
        head = f" bucket {b}/2: 2 members, up to {states} states\n"
        assert head in err
        after = err.split(head, 1)[1]
        assert "compiling the chunk program ... " in after
        assert re.search(rf"^eps_greedy_toy, bucket {b}/2: 100% 400/400 member-steps \[", after, re.M), err
    search.evaluate(EPS_AGENT, candidates, mdps, [0, 0], 200, log_period=50, n_buckets=2)
    assert capfd.readouterr().err == ""


def test_select_rejects_bad_scores_and_breaks_ties_by_order():
    assert search.select(np.array([[1.0, 3.0], [2.0, 2.0], [0.5, 3.5]])) == 0
    with pytest.raises(ValueError, match="finite"):
        search.select(np.array([[np.nan]]))


class _FakeResult:
    def __init__(self, final):
        self.final, self.run_s, self.compile_s = final, 1.0, 0.5

    def column(self, name):
        assert name == "normalized_cumulative_regret"
        return self.final[None]


def test_search_pipeline_with_a_fake_runner_and_the_tuned_file(tmp_path):
    # A fake runner scores each member by |c_1 - 0.5|: the winner is the candidate whose c_1 is closest to 0.5.
    calls = []

    def fake_run(agent, grid, n_steps, **kw):
        calls.append((grid.n_members, n_steps, kw["log_period"]))
        return _FakeResult(np.abs(np.asarray(grid.hparams.c_1, np.float64) - 0.5))

    budget = search.Budget(n_steps=1000, n_candidates=4, n_per_family=1, n_seeds=2, max_states=150)
    res = search.search("q_learning_episodic", budget, run=fake_run)
    assert res.labels == ["sample_0", "sample_1", "sample_2", "sample_3", "reference"]
    c1 = np.array([v["c_1"] for v in res.values])
    assert res.best == int(np.argmin(np.abs(c1 - 0.5)))
    assert res.scores.shape == (5, 2 * (7 - len(res.left_out)))
    assert sum(n for n, _, _ in calls) == res.scores.size and all(c[1:] == (1000, 100) for c in calls)
    assert res.left_out  # Taxi (240 states) is above max_states=150
    entry = search.provenance(res, budget, note="test")
    assert entry["values"] == res.values[res.best] and entry["budget"]["reduced"]
    assert entry["budget"]["seeds"] == [0, 1]
    assert len(entry["commit"]) == 40 or entry["commit"] == "unknown"
    path = tmp_path / "tuned.json"
    search.write_tuned(path, {"ucrl2": {"values": {"alpha_p": 1.0, "alpha_r": 0.5}}})
    search.write_tuned(path, {"q_learning_episodic": entry})
    data = json.loads(path.read_text())
    assert set(data["agents"]) == {"ucrl2", "q_learning_episodic"}
    hp = hparams.hparams_for("q_learning_episodic", path)
    assert float(hp.c_1) == entry["values"]["c_1"]
    assert float(hparams.hparams_for("ucrl2", path).alpha_r) == 0.5
    with pytest.raises(ValueError, match="no values for 'psrl_episodic'"):
        hparams.hparams_for("psrl_episodic", path)
    assert hparams.hparams_for("random_episodic", path) == hparams.hparams_for("random_episodic", "reference")


def test_tune_agents_records_wall_time_skips_agents_done_with_the_same_budget_and_reruns_others(
    tmp_path, monkeypatch
):
    from hardness.cli import benchmark as cli

    def tune(argv):
        return cli.tune_command(cli.build_parser().parse_args(["tune", *argv]))

    calls = []

    def fake_search(name, budget, *, n_buckets, progress, work_dir, run=None):
        calls.append((name, budget.n_steps, work_dir))
        values = [{"c_1": 0.2, "c_2": 0.3, "min_at": 0.1}, {"c_1": 0.9, "c_2": 0.3, "min_at": 0.1}]
        return search.SearchResult(name, ["sample_0", "reference"], values, np.array([[2.0, 4.0], [1.0, 1.0]]),
                                   [("RiverSwim/sample_0", 0), ("RiverSwim/sample_0", 1)], [], 1.0, 0.5)

    monkeypatch.setattr(search, "search", fake_search)
    out = tmp_path / "tuned.json"
    argv = ["--agents", "q_learning_episodic", "--steps", "100", "--candidates", "1", "--seeds", "2",
            "--out", str(out), "--work-dir", str(tmp_path / "work")]
    entries = tune(argv)
    entry = entries["q_learning_episodic"]
    assert entry["winner"] == "reference" and entry["objective"] == 1.0 and entry["wall_s"] >= 0
    assert calls[0][2].parent == tmp_path / "work" / "q_learning_episodic"  # one folder per agent and budget
    assert tune(argv) == {} and len(calls) == 1  # same budget: skipped
    assert tune([*argv, "--redo"]) and len(calls) == 2
    tune([*argv[:3], "200", *argv[4:]])  # another budget: searched again, in its own folder
    assert calls[2][1] == 200 and calls[2][2] != calls[0][2]
    assert json.loads(out.read_text())["agents"]["q_learning_episodic"]["budget"]["n_steps"] == 200
