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
