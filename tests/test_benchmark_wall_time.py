"""The wall-time extrapolation of benchmarks/benchmark_wall_time.py, on hand-worked numbers."""

import pytest
from benchmark_loader import load_benchmark


def test_extrapolation_interpolates_the_rate_in_states_and_scales_by_members_and_steps():
    wt = load_benchmark("benchmark_wall_time")
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
    wt = load_benchmark("benchmark_wall_time")
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
    wt = load_benchmark("benchmark_wall_time")
    m = dict(members=10, steps=100, run_s=0.08, steps2=300, run2_s=0.05)  # noise: the longer run was faster
    assert wt.rate_and_fixed(m) == pytest.approx((0.05 / (10 * 300), 0.0))
    assert wt.rate_and_fixed(dict(members=4, steps=50, run_s=2.0)) == pytest.approx((0.01, 0.0))  # one count


def test_two_step_counts_must_cut_the_runs_into_the_full_runs_chunks(tmp_path, capsys):
    # Each runner chunk ends with a checkpoint: 1 000 steps are 10 chunks of one record period, 3 000 steps 20 chunks,
    # so their difference would charge 10 checkpoints to the steps; from 2 000 steps on, 20 like the full run.
    wt = load_benchmark("benchmark_wall_time")
    assert [wt.n_chunks(n) for n in (1000, 2000, 3000, 4000, wt.FULL["n_steps"])] == [10, 20, 20, 20, 20]
    with pytest.raises(SystemExit):
        wt.main(["--work-dir", str(tmp_path), "--steps", "1000", "3000"])
    assert "chunks" in capsys.readouterr().err
