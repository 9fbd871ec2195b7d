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


def test_continuous_plan_count_bound_by_hand():
    """``1 + min(T, V log2(2 T / V))``, ``V = min(S A, T)``: 648 pairs over 500 000 steps; few steps."""
    cp = load_script("continuous_plan_wall_time")
    assert cp.plans_bound(108, 6) == pytest.approx(1 + 648 * math.log2(1e6 / 648))  # 6 864.4
    assert cp.plans_bound(2, 2, T=3) == pytest.approx(1 + 3 * math.log2(2.0))  # V = 3 pairs visited at most: 4
    assert cp.plans_bound(1, 2, T=4) == pytest.approx(1 + 2 * math.log2(4.0))  # 5 <= 1 + T
