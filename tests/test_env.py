"""Environment API: sampling frequencies, episode semantics, auto-reset, and lockstep batching."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import jaxmdp
from jaxmdp.experiment.members import member_mdp

from conftest import random_mdp
from stat_checks import Checks, key
from jaxpr_eqns import equations


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


@pytest.mark.nightly  # by default: test_properties_step.py, test_properties_runner.py
@pytest.mark.parametrize("episodic", [False, True])
def test_batched_trajectories_equal_single_runs(episodic):
    rng = np.random.default_rng(7)
    # Padded states and actions, padded states only, padded actions only (the stack is 8 x 4), the smallest MDP: every
    # single run is its own compilation, so four shapes.
    sizes = [(3, 2), (5, 4), (8, 2), (2, 2)]
    mdps = [random_mdp(rng, S, A, H=(S + 2 if episodic else None)) for S, A in sizes]
    batch = jaxmdp.stack(mdps)
    n_keys, n_steps = 1024, 12
    keys = jax.random.split(jax.random.key(3), n_keys)
    run = jax.jit(jax.vmap(jax.vmap(rollout, in_axes=(0, None, None)), in_axes=(None, 0, None)), static_argnums=2)
    out = run(keys, batch.strip(), n_steps)  # [4 MDPs, 1024 keys, n_steps]
    assert out[0].shape == (4, n_keys, n_steps)
    single = jax.jit(rollout, static_argnums=2)
    for i, m in enumerate(mdps):
        for j in (0, 511, 1023):
            ref = single(keys[j], m, n_steps)
            for got, want in zip(out, ref):
                np.testing.assert_array_equal(got[i, j], want)
        # Padding is never entered.
        assert int(jnp.max(out[0][i])) < m.n_states and int(jnp.max(out[1][i])) < m.n_actions


@pytest.mark.nightly  # by default: test_properties_step.py
@pytest.mark.parametrize("episodic", [False, True])
def test_step_member_reads_the_stack_with_the_results_of_step(episodic):
    # step_member on a stack of MDPs of different sizes (padded states and actions, several start states, Beta
    # rewards): bit for bit what step gives on each member's own MDP, vmapped over members as the runner steps them,
    # with invalid (padded) actions and episode resets among the steps.
    rng = np.random.default_rng(8)
    mdps = [random_mdp(rng, S, A, H=(S + 1 if episodic else None)) for S, A in [(5, 3), (3, 2), (4, 3)]]
    stack = jaxmdp.stack(mdps).strip()
    member = functools.partial(member_mdp, stack)
    index = jnp.asarray([0, 1, 2, 1, 0, 2, 1, 1], jnp.int32)

    def run(step):
        def body(carry, k):
            _, state = carry
            k_act, k_step = jax.random.split(k)
            action = jax.random.randint(k_act, (index.shape[0],), 0, 3)  # action 2 is padding for member 1
            keys = jax.random.split(k_step, index.shape[0])
            out = jax.vmap(step)(keys, state, action, index)
            return (out[0], out[1]), out

        _, state = jax.vmap(lambda k, i: jaxmdp.reset(k, member(i)))(jax.random.split(jax.random.key(1), 8), index)
        return jax.lax.scan(body, (state.state, state), jax.random.split(jax.random.key(2), 20))[1]

    own = jax.jit(lambda: run(lambda k, s, a, i: jaxmdp.step(k, s, a, member(i))))()
    shared = jax.jit(lambda: run(lambda k, s, a, i: jaxmdp.env.step_member(k, s, a, stack, i)))()
    for got, want in zip(jax.tree.leaves(shared), jax.tree.leaves(own)):
        np.testing.assert_array_equal(got, want)
    rewards, terminated = own[2], own[3]
    assert np.any(np.isnan(rewards)) and np.any(~np.isnan(rewards))  # invalid actions were among the steps
    assert np.any(terminated) == episodic


def test_step_member_refuses_what_it_cannot_step():
    rng = np.random.default_rng(9)
    stack = jaxmdp.stack([random_mdp(rng, 4, 2), random_mdp(rng, 3, 2)]).strip()
    _, state = jaxmdp.reset(jax.random.key(0), member_mdp(stack, 0))
    with pytest.raises(ValueError, match=r"member must be an index in \[0, 2\)"):
        jaxmdp.env.step_member(jax.random.key(1), state, 0, stack, 2)
    with pytest.raises(ValueError, match="action must be an integer"):
        jaxmdp.env.step_member(jax.random.key(1), state, 5, stack, 1)
    with pytest.raises(TypeError, match="stacked MDP"):
        jaxmdp.env.step_member(jax.random.key(1), state, 0, member_mdp(stack, 0), 0)


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


def dense_reference_step(key, state, action, mdp):
    """The step written on the dense arrays alone (cumulative sums over the whole ``P0`` and the successor row, the
    reward read from ``reward_mean``/``reward_conc`` at the reached state), with the documented random stream: one
    split into (reward key, uniform key), two uniforms (next state, reset)."""
    k_reward, k_uniform = jax.random.split(key)
    u_next, u_reset = jax.random.uniform(k_uniform, (2,), dtype=mdp.dtype)
    cdf = jnp.cumsum(mdp.succ_p[state.state, action])
    k = jnp.minimum(jnp.sum(cdf <= u_next * cdf[-1]), cdf.shape[-1] - 1)
    s_next = mdp.succ[state.state, action, k]
    reward = jaxmdp.env.sample_reward(k_reward, mdp, state.state, action, s_next)
    h_next = state.h + 1
    terminated = (h_next >= mdp.horizon) if mdp.episodic else jnp.zeros((), bool)
    p0 = jnp.cumsum(mdp.P0)
    s_reset = jnp.minimum(jnp.sum(p0 <= u_reset * p0[-1]), mdp.n_states - 1)
    new_state = jnp.where(terminated, s_reset, s_next)
    return new_state, jnp.where(terminated, 0, h_next), reward, terminated


def _sparse_and_dense_rollouts(key, mdp, n_steps):
    def body(carry, k):
        state, ref = carry
        k_act, k_step = jax.random.split(k)
        a = jaxmdp.sample_action(k_act, mdp)
        _, state, r, term, _, _ = jaxmdp.step(k_step, state, a, mdp)
        s2, h2, r2, term2 = dense_reference_step(k_step, ref, a, mdp)
        return (state, jaxmdp.EnvState(state=s2.astype(jnp.int32), h=h2.astype(jnp.int32))), (
            (state.state, state.h, r, term),
            (s2, h2, r2, term2),
        )

    _, state = jaxmdp.reset(key, mdp)
    _, (got, want) = jax.lax.scan(body, (state, state), jax.random.split(key, n_steps))
    return got, want


@functools.cache
def _step_test_mdps() -> dict:
    # Built on first use, not at collection (every xdist worker collects every module).
    rng = np.random.default_rng(11)
    noisy = jaxmdp.apply_noise(jaxmdp.make("DeepSea", episodic=True, seed=0, size=6), p_rand=0.3, p_lazy=0.2)
    return {
        "taxi": jaxmdp.make("Taxi", episodic=True, seed=0, size=5),  # 180 start states: the binary-search reset
        "rooms": jaxmdp.make("MiniGridRooms", episodic=False, seed=0, room_size=3),  # two start states
        "river-beta": jaxmdp.make("RiverSwim", episodic=True, seed=0, size=5, make_reward_stochastic=True),
        "deepsea-noisy": noisy,
        "random-episodic": random_mdp(rng, S=7, A=3, H=5),
        "random-continuous": random_mdp(rng, S=5, A=2),
    }


@pytest.mark.parametrize("name", ["taxi", "rooms", "river-beta", "deepsea-noisy", "random-episodic",
                                  "random-continuous"])
def test_sparse_step_samples_the_trajectories_of_the_dense_formulation(name):
    mdp = _step_test_mdps()[name]
    # The start lists, the reward slots and the start-list search reproduce the dense inverse CDFs draw for draw
    # (same keys, same trajectories), over 40 keys x 60 steps: many resets on every episodic MDP.
    run = jax.jit(jax.vmap(_sparse_and_dense_rollouts, in_axes=(0, None, None)), static_argnums=2)
    got, want = run(jax.random.split(jax.random.key(5), 40), mdp.strip(), 60)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(np.asarray(g), np.asarray(w).astype(np.asarray(g).dtype))
    if mdp.episodic:
        assert int(np.sum(np.asarray(got[3]))) >= 40 * (60 // int(mdp.H))


def _check_sparse_fields(m):
    """Start lists of one unbatched MDP against its dense ``P0``."""
    P0 = np.asarray(m.P0)
    starts = np.nonzero(P0 > 0)[0]
    n = starts.size
    np.testing.assert_array_equal(np.asarray(m.start)[:n], starts)
    np.testing.assert_array_equal(np.asarray(m.start)[n:], starts[-1])
    np.testing.assert_allclose(np.asarray(m.start_cdf)[:n], np.cumsum(P0.astype(np.float64))[starts], rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(m.start_cdf)[n:], np.asarray(m.start_cdf)[n - 1])


def test_sparse_fields_agree_with_the_dense_arrays_after_every_transform():
    rng = np.random.default_rng(2)
    mdps = [random_mdp(rng, S=4, A=2, H=3), jaxmdp.make("MiniGridRooms", episodic=True, seed=0, room_size=3)]
    mdps.append(jaxmdp.custom_mdp(np.full((3, 1, 3), 1 / 3), R=np.ones((3, 1)), P0=[0.0, 0.25, 0.75], H=2))
    for m in mdps:
        _check_sparse_fields(m)
        _check_sparse_fields(jaxmdp.apply_noise(m, p_rand=0.2, p_lazy=0.1))
        _check_sparse_fields(jaxmdp.permute_states(m, np.arange(m.n_states)[::-1]))
        _check_sparse_fields(jaxmdp.pad(m, m.n_states + 2, m.n_actions + 1, m.max_successors + 1, m.H, n_starts=9))
    batch = jaxmdp.stack(mdps)
    assert batch.max_starts == max(m.max_starts for m in mdps)
    for i, m in enumerate(jaxmdp.unstack(batch)):
        _check_sparse_fields(m)
        _check_sparse_fields(jax.tree.map(lambda x: x[i], batch))
        for field in ("start", "start_cdf"):
            np.testing.assert_array_equal(np.asarray(getattr(m, field)), np.asarray(getattr(mdps[i], field)))
    with pytest.raises(ValueError, match="start list"):
        jaxmdp.pad(mdps[0], 4, 2, mdps[0].max_successors, 3, n_starts=2)


def _out_shapes(jaxpr):
    """Shapes of every equation's outputs, nested jaxprs (jit, scan, cond) included."""
    for eqn in equations(jaxpr):
        yield from (v.aval.shape for v in eqn.outvars if hasattr(v.aval, "shape"))


@pytest.mark.parametrize("family, params", [("DeepSea", dict(size=20)), ("Taxi", dict(size=5))])
def test_step_does_no_work_of_size_S(family, params):
    # O(K) step: no intermediate of the traced step (MDP passed as an argument) has the number of states, or the
    # length of a long start list, as a dimension (the dense formulation summed over all of P0 at every step).
    m = jaxmdp.make(family, episodic=True, seed=0, **params).strip()
    banned = {m.n_states} | ({m.max_starts} if m.max_starts > 32 else set())
    assert m.n_states not in (m.n_actions, m.max_successors, m.max_starts)
    _, state = jaxmdp.reset(jax.random.key(0), m)
    closed = jax.make_jaxpr(jaxmdp.step)(jax.random.key(1), state, jnp.int32(1), m)
    shapes = list(_out_shapes(closed.jaxpr))
    assert len(shapes) > 20  # the walk saw the step's equations
    assert not [sh for sh in shapes if banned & set(sh)], shapes


def test_step_refuses_a_concrete_invalid_action():
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4)
    _, state = jaxmdp.reset(jax.random.key(0), m)
    for bad in (-1, 2, 7, np.int32(2), jnp.int32(-3)):
        with pytest.raises(ValueError, match=r"action must be an integer in \[0, 2\) \(A = 2\)"):
            jaxmdp.step(jax.random.key(1), state, bad, m)
    with pytest.raises(ValueError, match="A = 2"):
        jaxmdp.step(jax.random.key(1), state, 0.5, m)
    padded = jaxmdp.pad(m, m.n_states, 3, m.max_successors, m.H)
    with pytest.raises(ValueError, match=r"action \[?2\]? is a padded action.*valid actions: \[0, 1\] of A = 3"):
        jaxmdp.step(jax.random.key(1), state, 2, padded)
    jaxmdp.step(jax.random.key(1), state, 1, padded)  # a valid action still steps


def test_traced_invalid_action_is_a_flagged_no_op():
    # Under jit the action cannot be checked: an out-of-range or padded action leaves the state and h unchanged,
    # pays a NaN reward and never terminates the episode (even on its last step), in every member of a stacked batch.
    rng = np.random.default_rng(4)
    mdps = [random_mdp(rng, S=3, A=2, H=2), random_mdp(rng, S=5, A=4, H=2)]
    batch = jaxmdp.stack(mdps).strip()
    step = jax.jit(jax.vmap(jaxmdp.step, in_axes=(None, 0, 0, 0)))
    states = jaxmdp.EnvState(state=jnp.array([2, 4], jnp.int32), h=jnp.array([1, 1], jnp.int32))
    for actions in ([-1, 4], [2, -7], [3, 1_000_000]):  # member 0 has 2 valid actions (3 and 2 are padded)
        obs, new, r, term, trunc, info = step(jax.random.key(2), states, jnp.asarray(actions, jnp.int32), batch)
        invalid = np.array([a < 0 or a >= m.n_actions for a, m in zip(actions, mdps)])
        np.testing.assert_array_equal(np.isnan(np.asarray(r)), invalid)
        np.testing.assert_array_equal(np.asarray(new.state)[invalid], np.asarray(states.state)[invalid])
        np.testing.assert_array_equal(np.asarray(new.h)[invalid], 1)
        np.testing.assert_array_equal(np.asarray(obs)[invalid], np.asarray(states.state)[invalid])
        np.testing.assert_array_equal(np.asarray(info["final_observation"])[invalid], np.asarray(states.state)[invalid])
        assert not np.any(np.asarray(term)[invalid]) and not np.any(np.asarray(trunc))
        np.testing.assert_array_equal(np.asarray(term)[~invalid], True)  # h = 1 -> 2 = H: a valid action ends it
