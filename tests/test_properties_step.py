"""Property test: ``jaxmdp.step`` reads only the current member's row, whatever the action, on stacks of random MDPs
(tests/random_mdps.py; Hypothesis profiles in tests/hypothesis_profiles.py).

Every transition of the stack gets its own reward, a fingerprint of ``(member, s, a, s')`` (distinct dyadic numbers,
exact in float32), so the reward a step returns names the table entry it read: a step that read another member's,
state's or action's row, or a successor that the row does not hold, returns a reward that is not the fingerprint of
the transition it reports. Members have from 1 to 5 states and 1 to 3 actions inside a stack padded to 5 states and
3 actions, and every action from -1 to 3 is tried in every state, padded ones included.
"""

from __future__ import annotations

import dataclasses

import hypothesis_profiles
import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import jaxmdp
from jaxmdp.env import step_member
from random_mdps import A_PAD, S_PAD, Draw, draws

examples = hypothesis_profiles.examples

N_MEMBERS = 3
#: Actions tried: one below the range, every padded action of a member, one above the range.
ACTIONS = np.arange(-1, A_PAD + 1)
#: Keys per (member, state, action, time) combination.
N_KEYS = 2


def fingerprint(m: int, s: int, a: int, t: int) -> float:
    """The reward of transition ``(s, a, t)`` of member ``m``: distinct for every combination, exact in float32."""
    return (((m * S_PAD + s) * A_PAD + a) * S_PAD + t + 1) / 512


def with_fingerprints(draw: Draw, m: int) -> Draw:
    S, A = draw.n_states, draw.n_actions
    codes = [[[int(fingerprint(m, s, a, t) * 512) for t in range(S)] for a in range(A)] for s in range(S)]
    return dataclasses.replace(draw, rewards=codes, denom=512, conc=None)


def _combos(horizons: np.ndarray, seed: int):
    """Every (member, state, action, in-episode time, key): times 0 and ``horizon - 1`` (the last step) for an
    episodic stack, 0 for a continuous one."""
    rows = []
    for m in range(N_MEMBERS):
        times = sorted({0, int(horizons[m]) - 1}) if horizons is not None else [0]
        for s in range(S_PAD):
            for a in ACTIONS:
                for h in times:
                    rows += [(m, s, a, h)] * N_KEYS
    rows = np.asarray(rows, np.int32)
    keys = jax.random.split(jax.random.key(seed), len(rows))
    return rows, keys


@jax.jit
def _steps(stack, members, states, actions, times, keys):
    """The steps of :func:`_combos` twice: ``step_member`` on the stack and ``step`` on each member's slice."""

    def by_member(key, m, s, a, h):
        return step_member(key, jaxmdp.EnvState(s, h), a, stack, m)

    def by_slice(key, m, s, a, h):
        return jaxmdp.step(key, jaxmdp.EnvState(s, h), a, jax.tree.map(lambda x: x[m], stack))

    args = (keys, members, states, actions, times)
    return jax.vmap(by_member)(*args), jax.vmap(by_slice)(*args)


@given(setting=st.booleans().flatmap(
    lambda e: st.lists(draws(episodic=e), min_size=N_MEMBERS, max_size=N_MEMBERS)), seed=st.integers(0, 2**31 - 1))
@settings(max_examples=examples(15))
def test_step_reads_only_the_members_row(setting: list[Draw], seed: int):
    draws_ = [with_fingerprints(d, m) for m, d in enumerate(setting)]
    episodic = draws_[0].horizon is not None
    stack = jaxmdp.stack([d.padded() for d in draws_])
    horizons = np.asarray([d.horizon for d in draws_]) if episodic else None
    rows, keys = _combos(horizons, seed)
    m, s, a, h = (jnp.asarray(rows[:, i]) for i in range(4))
    by_member, by_slice = _steps(stack, m, s, a, h, keys)
    # step_member is step on the member's own MDP, bit for bit.
    for x, y in zip(jax.tree.leaves(by_member), jax.tree.leaves(by_slice)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    obs, state, reward, terminated, truncated, info = jax.tree.map(np.asarray, by_member)
    reached = info["final_observation"]
    assert not truncated.any()
    arrays = [d.arrays() for d in draws_]
    for i, (mi, si, ai, hi) in enumerate(rows):
        d = draws_[mi]
        S, A = d.n_states, d.n_actions
        T, _, P0 = arrays[mi]
        where = f"member {mi} (S={S}, A={A}), state {si}, action {ai}, h={hi}"
        if not 0 <= ai < A:  # a padded or out-of-range action: the flagged no-op
            assert np.isnan(reward[i]), where
            assert (state.state[i], state.h[i], reached[i], terminated[i]) == (si, hi, si, False), where
            continue
        t = reached[i]
        if si >= S:  # a padding state: absorbing, pays nothing
            assert (t, reward[i]) == (si, 0.0), where
        else:
            assert 0 <= t < S and T[si, ai, t] > 0, f"{where}: reached {t}"
            assert reward[i] == np.float32(fingerprint(mi, si, ai, t)), f"{where}: reward {reward[i] * 512}"
        last = episodic and hi + 1 == d.horizon
        assert terminated[i] == last, where
        if last:
            assert state.h[i] == 0 and P0[state.state[i]] > 0, f"{where}: reset to {state.state[i]}"
        else:
            assert (state.state[i], state.h[i]) == (t, hi + 1), where
