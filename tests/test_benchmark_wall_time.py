"""The wall-time extrapolation of scripts/benchmark_wall_time.py, on hand-worked numbers."""

import math

import pytest
from script_loader import load_script


def test_extrapolation_interpolates_the_rate_in_states_and_scales_by_members_and_steps():
    wt = load_script("benchmark_wall_time")
    measured = [  # 1e-6 and 3e-6 run seconds per member-step at 100 and 300 states
        dict(set="episodic ergodic", agent="a", members=10, steps=1000, max_states=100, run_s=0.01, compile_s=10.0),
        dict(set="episodic ergodic", agent="a", members=20, steps=500, max_states=300, run_s=0.03, compile_s=30.0),
    ]
    full = [dict(set="episodic ergodic", agent="a", members=40, max_states=200),
            dict(set="episodic communicating", agent="a", members=20, max_states=400),  # same type, clipped at 300
            dict(set="continuous ergodic", agent="a", members=20, max_states=100)]  # no continuous measurement
    rows = wt.extrapolate(full, measured)
    n = wt.FULL["n_steps"]
    assert rows[0]["run_s"] == pytest.approx(2e-6 * 40 * n) and rows[0]["compile_s"] == 20.0
    assert rows[1]["run_s"] == pytest.approx(3e-6 * 20 * n) and rows[1]["compile_s"] == 20.0
    assert rows[2]["run_s"] is None and rows[2]["compile_s"] is None


def test_two_step_counts_separate_the_fixed_cost_and_the_scalings_differ_by_members():
    wt = load_script("benchmark_wall_time")
    # 10 members: 1.5 s for 100 steps, 2.5 s for 1 100 -> 1e-4 s per member-step, 1.4 s fixed; at 300 states 20
    # members: 3.0 s for 100 steps, 7.0 s for 1 100 -> 2e-4 s per member-step, 2.6 s fixed.
    measured = [
        dict(set="continuous ergodic", agent="a", members=10, max_states=100, steps=100, run_s=1.5, steps2=1100,
             run2_s=2.5, compile_s=1.0),
        dict(set="continuous ergodic", agent="a", members=20, max_states=300, steps=100, run_s=3.0, steps2=1100,
             run2_s=7.0, compile_s=3.0),
    ]
    assert wt.rate_and_fixed(measured[0]) == pytest.approx((1e-4, 1.4))
    assert wt.rate_and_fixed(measured[1]) == pytest.approx((2e-4, 2.6))
    full = [dict(set="continuous ergodic", agent="a", members=40, max_states=200)]
    n = wt.FULL["n_steps"]
    (row,) = wt.extrapolate(full, measured)  # 1.5e-4 s per member-step and 2.0 s fixed at 200 states
    assert row["run_s"] == pytest.approx(2.0 + 1.5e-4 * 40 * n) and row["compile_s"] == 2.0
    # Per lockstep step: 1e-3 s (10 members) and 4e-3 s (20 members) -> 2.5e-3 s at 200 states, whatever the members.
    (row,) = wt.extrapolate(full, measured, "lockstep-step")
    assert row["run_s"] == pytest.approx(2.0 + 2.5e-3 * n)
    with pytest.raises(ValueError, match="scaling"):
        wt.extrapolate(full, measured, "per-member")


def test_a_second_run_that_is_not_slower_charges_everything_to_its_steps():
    wt = load_script("benchmark_wall_time")
    m = dict(members=10, steps=100, run_s=0.08, steps2=300, run2_s=0.05)  # noise: the longer run was faster
    assert wt.rate_and_fixed(m) == pytest.approx((0.05 / (10 * 300), 0.0))
    assert wt.rate_and_fixed(dict(members=4, steps=50, run_s=2.0)) == pytest.approx((0.01, 0.0))  # one count


def test_continuous_plan_count_bound_by_hand():
    """``1 + min(T, V log2(2 T / V))``, ``V = min(S A, T)``: 648 pairs over 500 000 steps; few steps."""
    cp = load_script("continuous_plan_wall_time")
    assert cp.plans_bound(108, 6) == pytest.approx(1 + 648 * math.log2(1e6 / 648))  # 6 864.4
    assert cp.plans_bound(2, 2, T=3) == pytest.approx(1 + 3 * math.log2(2.0))  # V = 3 pairs visited at most: 4
    assert cp.plans_bound(1, 2, T=4) == pytest.approx(1 + 2 * math.log2(4.0))  # 5 <= 1 + T


def test_continuous_plan_extrapolation_by_hand():
    """Two measured buckets of agent ``a`` (100 and 300 states), one between them and one past the end, unmeasured;
    agent ``b`` measured only for its plans; a row of an older ``measured.json`` (no ``c_one``) left out."""
    cp = load_script("continuous_plan_wall_time")
    rows = [
        dict(batch="a0", agent="a", members=20, shards=2, slots=2, max_states=100, plans=1000.0,
             c_round=0.02, c_one=0.015, c_step=1e-6),  # 0.01 s a slot
        dict(batch="a1", agent="a", members=40, shards=2, slots=4, max_states=200, plans=4000.0),
        dict(batch="a2", agent="a", members=10, shards=2, slots=1, max_states=300, plans=3000.0,
             c_round=0.03, c_one=0.03, c_step=3e-6),  # 0.03 s a slot
        dict(batch="a3", agent="a", members=10, shards=2, slots=1, max_states=500, plans=100.0),
        dict(batch="b0", agent="b", members=4, shards=2, slots=1, max_states=50, plans=10.0, c_round=1.0, c_one=1.0),
        dict(batch="b1", agent="b", members=4, shards=2, slots=1, max_states=60, plans=10.0, c_round=1.0),
    ]
    T = 1000
    result = cp.extrapolate(rows, T=T)
    a0, a1, a2, a3, b0, b1 = result["rows"]
    # a1, halfway in states: 0.02 s a slot x 4 slots, c_one 0.0225, c_step 2e-6; a3 clipped at a2's rates.
    assert a1["c_round"] == pytest.approx(0.08) and a1["c_one"] == pytest.approx(0.0225)
    assert a1["c_step"] == pytest.approx(2e-6) and a1["c_round_interpolated"] and not a0.get("c_round_interpolated")
    assert (a3["c_round"], a3["c_one"], a3["c_step"]) == pytest.approx((0.03, 0.03, 3e-6))
    assert a0["run_s_low"] == pytest.approx(1e-6 * 20 * T + 1000 / 2 * 0.02 / 2)  # 0.02 + 5
    assert a0["run_s_high"] == pytest.approx(1e-6 * 20 * T + 1000 / 2 * 0.015)  # 0.02 + 7.5
    assert a1["run_s_low"] == pytest.approx(2e-6 * 40 * T + 4000 / 2 * 0.08 / 4)  # 0.08 + 40
    assert a1["run_s_high"] == pytest.approx(2e-6 * 40 * T + 4000 / 2 * 0.0225)  # 0.08 + 45
    assert b0["steps_s"] == 0.0 and b0["run_s_low"] == b0["run_s_high"] == pytest.approx(5.0)  # no step cost: 0
    # b1's c_one is missing but another row of b has one: it is interpolated (clipped at b0's), so b1 counts.
    assert b1["c_one_interpolated"] and b1["run_s_low"] == pytest.approx(5.0)
    total_low = sum(r["run_s_low"] for r in (a0, a1, a2, a3, b0, b1))
    assert result["run_s_low"] == pytest.approx(total_low) and result["T"] == T


def test_continuous_plan_extrapolation_leaves_out_rows_it_cannot_cost():
    cp = load_script("continuous_plan_wall_time")
    rows = [dict(batch="a0", agent="a", members=2, shards=1, slots=1, max_states=10, plans=5.0, c_round=1.0),
            dict(batch="b0", agent="b", members=2, shards=1, slots=1, max_states=10, plans=5.0, c_step=1e-3)]
    result = cp.extrapolate(rows, T=100)
    assert "run_s_low" not in result["rows"][0] and "run_s_low" not in result["rows"][1]
    assert result["run_s_low"] == result["run_s_high"] == 0


def test_in_program_seconds_loops_over_calls_with_fresh_keys():
    """The plan timing of scripts/continuous_plan_wall_time.py: each run of the loop of ``m`` calls passes
    ``fold_in(key, i)``, ``i < m``, and both loop lengths run ``1 + repeats`` times (a first, compiling run)."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    pcp = load_script("profile_continuous_plans")
    seen = []

    def fn(keys, states):
        jax.debug.callback(lambda k: seen.append(tuple(np.asarray(k).ravel())), jax.random.key_data(keys))
        return dict(x=states["x"] * 2.0, n=states["n"] + 1)

    keys = jax.random.split(jax.random.key(0), 2)
    t = pcp.in_program_seconds(fn, keys, dict(x=jnp.ones(3), n=jnp.zeros(3, jnp.int32)), calls=3, repeats=2)
    assert t >= 0.0 and math.isfinite(t)
    assert len(seen) == (1 + 2) * (1 + 4)
    expected = {tuple(np.asarray(jax.random.key_data(jax.vmap(lambda k: jax.random.fold_in(k, i))(keys))).ravel())
                for i in range(4)}
    assert set(seen) == expected


def test_two_step_counts_must_cut_the_runs_into_the_full_runs_chunks(tmp_path, capsys):
    # Each runner chunk ends with a checkpoint: 1 000 steps are 10 chunks of one record period, 3 000 steps 20 chunks,
    # so their difference would charge 10 checkpoints to the steps; from 2 000 steps on, 20 like the full run.
    wt = load_script("benchmark_wall_time")
    assert [wt.n_chunks(n) for n in (1000, 2000, 3000, 4000, wt.FULL["n_steps"])] == [10, 20, 20, 20, 20]
    with pytest.raises(SystemExit):
        wt.main(["--out", str(tmp_path), "--steps", "1000", "3000"])
    assert "chunks" in capsys.readouterr().err
