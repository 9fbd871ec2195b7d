"""The doubling-trick epoch schedule on a hand-worked visit sequence."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from agents.epochs import epoch_schedule, record_visit, start_epoch

def _replay(visits):
    sched = epoch_schedule(2, 2)
    step = jax.jit(record_visit)
    ends = []
    for s, a in visits:
        sched, end = step(sched, jnp.int32(s), jnp.int32(a))
        ends.append(bool(end))
        if end:
            sched = start_epoch(sched)
    return sched, ends


def test_doubling_rule_hand_worked_sequence():
    visits = [(0, 0), (0, 0), (0, 0), (0, 0), (0, 1), (0, 0), (0, 1), (1, 0), (0, 0), (0, 0), (0, 0), (0, 0), (0, 0)]
    expected = [
        True,  # (0,0) N=1 nu=1, threshold max(1, 0) = 1: first visit ends the epoch
        True,  # (0,0) N=2 nu=1, threshold max(1, 1) = 1
        False,  # (0,0) N=3 nu=1, threshold 2
        True,  # (0,0) N=4 nu=2, threshold 2
        True,  # (0,1) N=1 nu=1: first visit
        False,  # (0,0) N=5 nu=1, threshold 4
        True,  # (0,1) N=2 nu=1, threshold 1
        True,  # (1,0) first visit
        False,  # (0,0) N=6 nu=1, threshold 5  (the epoch restarted after (1,0); nu counts from there)
        False,  # (0,0) N=7 nu=2, threshold 5
        False,  # (0,0) N=8 nu=3, threshold 5
        False,  # (0,0) N=9 nu=4, threshold 5
        True,  # (0,0) N=10 nu=5, threshold 5: the count doubled since the epoch began
    ]
    sched, ends = _replay(visits)
    assert ends == expected
    np.testing.assert_array_equal(sched.visits, [[10, 2], [1, 0]])
    np.testing.assert_array_equal(sched.epoch_visits, 0)


def test_epoch_count_is_logarithmic_for_a_single_pair():
    # One pair visited 2^k times: epochs end at N = 1, 2, 4, 8, ... (k + 1 epochs).
    sched, ends = _replay([(1, 1)] * 64)
    np.testing.assert_array_equal(np.flatnonzero(ends) + 1, [1, 2, 4, 8, 16, 32, 64])
