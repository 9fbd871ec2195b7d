"""Environment API: sampling frequencies, episode semantics, auto-reset, and lockstep batching."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import jaxmdp

from conftest import random_mdp
from stat_checks import Checks, key


def rollout(key, mdp, n_steps):
    """Random-action trajectory: (states, actions, rewards, terminated) of n_steps steps."""
    k_reset, k_run = jax.random.split(key)
    obs, state = jaxmdp.reset(k_reset, mdp)

    def body(carry, k):
        obs, state = carry
        k_act, k_step = jax.random.split(k)
        a = jaxmdp.sample_action(k_act, mdp)
        obs2, state2, r, term, trunc, info = jaxmdp.step(k_step, state, a, mdp)
        return (obs2, state2), (obs, a, r, term)

    _, out = jax.lax.scan(body, (obs, state), jax.random.split(k_run, n_steps))
    return out


next_states = jax.jit(jax.vmap(jaxmdp.env.sample_next_state, (0, None, None, None)))
rewards = jax.jit(jax.vmap(jaxmdp.env.sample_reward, (0, None, None, None, 0)))


@pytest.mark.statistical(p=1.2e-6)
def test_next_state_and_reward_frequencies_match_the_model():
    # Next-state counts are Binomial(n, p) exactly; the rewards after each next state are i.i.d. in [0, 1] with the
    # model's Beta (mean and variance by Bernstein) or its point mass. At most 4 + 2 x 4 = 12 checks at 1e-7 each
    # (tests/stat_checks.py): false-failure probability <= 1.2e-6 for the test.
    rng = np.random.default_rng(0)
    m = random_mdp(rng, S=4, A=2)
    s, a, n = 2, 1, 200_000
    keys = jax.random.split(key(1), n)
    nxt = next_states(keys, m, jnp.int32(s), jnp.int32(a))
    counts = np.bincount(np.asarray(nxt), minlength=4)
    p = np.asarray(m.T[s, a], np.float64)
    checks = Checks()
    for t in range(4):
        if p[t] > 0:
            checks.binomial(int(counts[t]), n, p[t], f"next state {t}")
        else:
            assert counts[t] == 0
    # Rewards: given the next state, Beta(mean conc, (1 - mean) conc) or a point mass at reward_mean.
    rew = rewards(keys, m, jnp.int32(s), jnp.int32(a), nxt)
    for t in range(4):
        if p[t] > 0.05:
            sel = np.asarray(rew, np.float64)[np.asarray(nxt) == t]
            mean, conc = float(m.reward_mean[s, a, t]), float(m.reward_conc[s, a, t])
            if conc == 0:
                np.testing.assert_array_equal(sel, np.float32(mean))
            else:
                checks.bounded_moments(sel, stats.beta(mean * conc, (1 - mean) * conc), 0.0, 1.0, f"reward after {t}")
    assert checks.false_failure_bound() <= 1.2e-6


def test_episode_has_exactly_horizon_actions_and_auto_resets():
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4, randomize_actions=False)
    assert m.H == 4
    obs, actions, rewards, term = jax.jit(rollout, static_argnums=2)(jax.random.key(0), m, 20)
    np.testing.assert_array_equal(np.nonzero(np.asarray(term))[0], [3, 7, 11, 15, 19])
    # After each termination the next observation is a fresh start (P0 is X = 0).
    np.testing.assert_array_equal(np.asarray(obs)[[4, 8, 12, 16]], 0)


def test_final_observation_is_the_state_reached():
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=3, randomize_actions=False)
    _, state = jaxmdp.reset(jax.random.key(0), m)
    state = state.replace(state=jnp.int32(1), h=jnp.int32(2))
    obs, new, r, term, trunc, info = jaxmdp.step(jax.random.key(1), state, 1, m)  # RIGHT from X=1 at h=2
    assert bool(term) and not bool(trunc)
    assert int(info["final_observation"]) == 2 and int(obs) == 0 and int(new.h) == 0
    assert float(info["discount"]) == 0.0


def test_continuous_never_terminates():
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)
    _, _, _, term = rollout(jax.random.key(0), m, 50)
    assert not bool(jnp.any(term))


@pytest.mark.parametrize("episodic", [False, True])
def test_batched_trajectories_equal_single_runs(episodic):
    rng = np.random.default_rng(7)
    sizes = [(3, 2), (5, 3), (8, 2), (4, 4), (6, 3), (2, 2), (7, 4), (5, 2)]
    mdps = [random_mdp(rng, S, A, H=(S + 2 if episodic else None)) for S, A in sizes]
    batch = jaxmdp.stack(mdps)
    n_keys, n_steps = 1024, 12
    keys = jax.random.split(jax.random.key(3), n_keys)
    run = jax.jit(jax.vmap(jax.vmap(rollout, in_axes=(0, None, None)), in_axes=(None, 0, None)), static_argnums=2)
    out = run(keys, batch.strip(), n_steps)  # [8 MDPs, 1024 keys, n_steps]
    assert out[0].shape == (8, n_keys, n_steps)
    single = jax.jit(rollout, static_argnums=2)
    for i, m in enumerate(mdps):
        for j in (0, 511, 1023):
            ref = single(keys[j], m, n_steps)
            for got, want in zip(out, ref):
                np.testing.assert_array_equal(got[i, j], want)
        # Padding is never entered.
        assert int(jnp.max(out[0][i])) < m.n_states and int(jnp.max(out[1][i])) < m.n_actions


def test_stochastic_rewards_flag_is_static_and_exact():
    det = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)
    sto = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4, make_reward_stochastic=True)
    assert not det.stochastic_rewards and sto.stochastic_rewards
    assert jaxmdp.stack([det, sto]).stochastic_rewards
    # deterministic rewards are returned exactly, whatever the key
    r = jax.vmap(lambda k: jaxmdp.env.sample_reward(k, det, jnp.int32(0), jnp.int32(0), jnp.int32(0)))(
        jax.random.split(jax.random.key(0), 8)
    )
    np.testing.assert_array_equal(r, np.float32(0.005))
    # a stochastic MDP whose flag is forced on still returns point masses exactly
    forced = det.replace(stochastic_rewards=True)
    np.testing.assert_array_equal(
        jaxmdp.env.sample_reward(jax.random.key(1), forced, jnp.int32(0), jnp.int32(0), jnp.int32(0)), np.float32(0.005)
    )
