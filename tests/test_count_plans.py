"""scripts/count_plans.py: plans counted in the runner, and the wall-time extrapolation's use of them."""

import json

import numpy as np
import pytest
from script_loader import load_script
from test_runner import SCRIPTED, ScriptedHParams, river_swim

from jaxmdp.experiment import runner


@pytest.mark.parametrize("episodic", [False, True])
def test_counting_plans_counts_the_runner_s_plans_and_changes_nothing_else(episodic):
    # The scripted agent asks for a plan every `plan_every` steps and counts its own plans. Periods 5, 5, 7: at a
    # multiple of 5 two of three members are due, more than half, so the runner plans the whole batch and keeps
    # the plans of the due members only; the third member must not count those.
    cp = load_script("count_plans")
    agent = SCRIPTED[episodic]
    g = runner.product([river_swim(episodic)], [ScriptedHParams(plan_every=p) for p in (5, 5, 7)], seeds=[0])
    plain = runner.run(agent, g, 1050, log_period=100, n_records=4)
    counted = runner.run(cp.counting_plans(agent), g, 1050, log_period=100, n_records=4)
    want = [1 + 1049 // 5, 1 + 1049 // 5, 1 + 1049 // 7]  # the initial plan, then before every due step
    np.testing.assert_array_equal(counted.agent_state[1], want)
    np.testing.assert_array_equal(counted.agent_state[0].plans, want)
    np.testing.assert_array_equal(counted.values, plain.values)
    np.testing.assert_array_equal(counted.agent_state[0].c, plain.agent_state.c)


def test_ucrl2_counted_at_least_once_per_pair_it_visited_and_at_most_the_bound(tmp_path, monkeypatch):
    # Every first visit of a pair ends UCRL2's epoch (agents/epochs.py), so a member plans at least once per pair it
    # visited (the initial plan, and a plan after each first visit but perhaps the last step's); a pair ends at most
    # 1 + log2 N epochs, which bounds the count by the member's own visits, and that by the epoch bound. Then a second
    # call on the same file measures nothing again.
    cp = load_script("count_plans")
    out = tmp_path / "counts.json"
    results = cp.main(["--out", str(out), "--agents", "ucrl2", "--sets", "continuous ergodic", "--labels",
                       "RiverSwim/prms_0", "--steps", "3000", "--seeds", "2", "--log-period", "1000"])
    (entry,) = results.values()
    assert entry["states"] == 30 and entry["actions"] == 2 and entry["steps"] == 3000
    assert json.loads(out.read_text()) == results
    for plans, pairs, cap in zip(entry["plans"], entry["pairs_visited"], entry["visits_bound"]):
        assert 10 <= pairs <= plans <= cap <= entry["bound"]
        assert plans > pairs  # doubled epochs too, not only first visits
    monkeypatch.setattr(cp, "count", lambda *a: pytest.fail("measured again"))
    assert cp.main(["--out", str(out), "--agents", "ucrl2", "--sets", "continuous ergodic", "--labels",
                    "RiverSwim/prms_0", "--steps", "3000"]) == results
    with pytest.raises(ValueError, match="--sets must name continuous settings"):
        cp.main(["--out", str(out), "--sets", "episodic ergodic"])
    with pytest.raises(ValueError, match=r"--labels \['RiverSwim/prms_9'\] are not MDPs"):
        cp.main(["--out", str(out), "--sets", "continuous ergodic", "--labels", "RiverSwim/prms_9"])


def test_member_plans_uses_a_count_measured_at_the_same_steps_else_the_bound():
    wt = load_script("continuous_plan_wall_time")
    key = wt.plan_count_key("ucrl2", "continuous ergodic", "RiverSwim/prms_0")
    counts = {key: dict(steps=wt.T_FULL, plans=[100, 300])}
    assert wt.member_plans("ucrl2", "continuous ergodic", "RiverSwim/prms_0", 30, 2, counts) == (200.0, True)
    bound = wt.plans_bound(30, 2)
    assert wt.member_plans("psrl_continuous", "continuous ergodic", "RiverSwim/prms_0", 30, 2, counts) == (bound, False)
    assert wt.member_plans("ucrl2", "continuous ergodic", "RiverSwim/prms_0", 30, 2, None) == (bound, False)
    short = {key: dict(steps=1000, plans=[100, 300])}
    assert wt.member_plans("ucrl2", "continuous ergodic", "RiverSwim/prms_0", 30, 2, short) == (bound, False)


def test_the_continuous_step_cost_is_the_difference_of_two_runs_cut_like_the_full_run(tmp_path, monkeypatch):
    # 5 s fixed per call plus 1e-4 s per member-step: the difference of the two runs gives the rate alone. Runs of
    # 300 and 1 300 steps would be cut into 3 and 13 chunks (a checkpoint each), the full run into 20: refused.
    import agents as agent_registry

    cp = load_script("continuous_plan_wall_time")
    with pytest.raises(SystemExit):
        cp.main(["--out", str(tmp_path), "--skip-plans", "--steps", "300", "1300"])
    planning = []

    def measure(set_name, agent, labels, seeds, n, out):
        planning.append(bool(agent_registry.AGENTS[agent].needs_plan(None)))
        return dict(set=set_name, agent=agent, members=20, max_states=948, steps=n, run_s=5.0 + 1e-4 * 20 * n,
                    compile_s=30.0)

    monkeypatch.setattr(cp.wall_time, "measure", measure)
    saved = agent_registry.AGENTS["ucrl2"]
    m = cp.step_cost("continuous ergodic", "ucrl2", ["MiniGridRooms/prms_1"], (2000, 4000), tmp_path)
    assert m["c_step"] == pytest.approx(1e-4) and m["step_fixed_s"] == pytest.approx(5.0)
    assert planning == [False, False] and agent_registry.AGENTS["ucrl2"] is saved
