"""The lockstep runner: indicator accounting against numpy, baselines, batching, determinism, chunking, resume and
bad input.

Compilation dominates the cost of these tests, so they share a few shapes: RiverSwim size 5 (deterministic) and a
2-member grid wherever possible.
"""

from __future__ import annotations

import csv
import gc
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct

import agents
import jaxmdp
from jaxmdp.experiment import lockstep, runner
from jaxmdp.experiment.agent_interface import Agent, plans_whole, spec_of
from jaxmdp.experiment.indicators import CSV_COLUMNS
from conftest import random_mdp
from numpy_reference import finite_horizon_eval, finite_horizon_optimal, one_hot

# ---------------------------------------------------------------------------------------------------------------
# A scripted agent whose policy is a known function of the number of updates c: every state takes action
# (c // 3) % A. It acts with that policy, so on a deterministic MDP its whole trajectory is known. It asks to plan
# whenever c is a positive multiple of its hyperparameter ``plan_every`` and counts its plans.
# ---------------------------------------------------------------------------------------------------------------


class ScriptedHParams(struct.PyTreeNode):
    plan_every: int | jax.Array = 5


class ScriptedState(struct.PyTreeNode):
    c: jax.Array
    plans: jax.Array
    plan_every: jax.Array
    n_states: int = struct.field(pytree_node=False)
    n_actions: int = struct.field(pytree_node=False)
    H: int | None = struct.field(pytree_node=False)


def scripted_action(c, A):
    return (c // 3) % A


def _scripted(episodic: bool) -> Agent:
    def init(key, spec, hp):
        return ScriptedState(jnp.int32(0), jnp.int32(0), jnp.asarray(hp.plan_every, jnp.int32), spec.n_states,
                             spec.n_actions, spec.H)

    def policy(state):
        pi = jax.nn.one_hot(scripted_action(state.c, state.n_actions), state.n_actions)
        shape = (state.n_states, state.n_actions) if state.H is None else (state.H, state.n_states, state.n_actions)
        return jnp.broadcast_to(pi, shape)

    return Agent(
        name=f"scripted_{'episodic' if episodic else 'continuous'}",
        episodic=episodic,
        default_hparams=ScriptedHParams(),
        init=init,
        act=lambda key, state, obs, h: scripted_action(state.c, state.n_actions).astype(jnp.int32),
        update=lambda state, tr: state.replace(c=state.c + 1),
        policy=policy,
        needs_plan=lambda state: (state.c > 0) & (state.c % state.plan_every == 0),
        plan=lambda key, state: state.replace(plans=state.plans + 1),
    )


SCRIPTED = {False: _scripted(False), True: _scripted(True)}


def river_swim(episodic: bool, **kw):
    return jaxmdp.make("RiverSwim", episodic=episodic, seed=0, size=5, randomize_actions=False, **kw)


def expected_accounting(mdp, n_steps, log_period):
    """numpy: cumulative regret, normalised regret, expected reward and sampled reward of the scripted agent on a
    deterministic MDP (deterministic rewards), at every step count."""
    T, R, P0 = (np.asarray(x, np.float64) for x in (mdp.T, mdp.R, mdp.P0))
    S, A = R.shape
    if mdp.episodic:
        H = mdp.H
        v_opt, v_min = finite_horizon_optimal(T, R, H), finite_horizon_optimal(T, R, H, -1.0)
        def inst(c):
            v = finite_horizon_eval(T, R, one_hot(np.full(S, scripted_action(c, A)), A), H)
            gap = P0 @ (v_opt - v)
            return gap / H, gap / (P0 @ (v_opt - v_min)), P0 @ v / H
    else:
        # RiverSwim: constant policies are unichain (LEFT: 0.005 at the left end; RIGHT: 1 at the right end);
        # optimal gain 1, minimal gain 0 (oscillating in the middle).
        def inst(c):
            g = 0.005 if scripted_action(c, A) == 0 else 1.0
            return 1.0 - g, 1.0 - g, g
    sums = np.zeros((n_steps + 1, 4))
    acc = np.zeros(4)
    last = 0
    s, h, reward = int(np.argmax(P0)), 0, 0.0
    for t in range(n_steps):
        a = scripted_action(t, A)
        reward += R[s, a]
        s, h = int(np.argmax(T[s, a])), h + 1
        if mdp.episodic and h == mdp.H:
            s, h = int(np.argmax(P0)), 0
        c = t + 1
        if c % log_period == 0 or c == n_steps:
            r, nr, er = inst(c)
            acc += np.array([r, 0.0, er, nr]) * (c - last)
            last = c
        sums[c] = acc
        sums[c, 1] = reward
    return sums


@pytest.mark.parametrize("episodic", [False, True])
def test_accounting_matches_numpy(episodic):
    mdp = river_swim(episodic)
    g = runner.product([mdp], [ScriptedHParams(plan_every=5), ScriptedHParams(plan_every=7)], seeds=[0])
    res = runner.run(SCRIPTED[episodic], g, 1050, log_period=100, n_records=4)
    np.testing.assert_array_equal(res.steps, [300, 600, 900, 1050])
    want = expected_accounting(mdp, 1050, 100)[res.steps]
    for b in range(2):
        np.testing.assert_allclose(res.values[:, b], want, rtol=1e-5, atol=1e-4)
    # Planning: once after init, then before every step whose state asks for it (member-specific periods).
    np.testing.assert_array_equal(res.agent_state.plans, [1 + 1049 // 5, 1 + 1049 // 7])
    np.testing.assert_array_equal(res.agent_state.c, [1050, 1050])


class FirstKeyState(struct.PyTreeNode):
    plans: jax.Array
    first_key: jax.Array


def test_every_member_plans_once_before_its_first_action_with_its_initialisation_key():
    # An agent that never asks for a plan is still planned once, before its first action, with the key
    # fold_in(split(member key, 4)[3], 2) (the initialisation sub-key's "plan" tag); an agent without plan() has none.
    agent = Agent(
        name="first_key", episodic=False, default_hparams=ScriptedHParams(),
        init=lambda key, spec, hp: FirstKeyState(jnp.int32(0), jnp.zeros((2,), jnp.uint32)),
        act=lambda key, state, obs, h: jnp.int32(0), update=lambda state, tr: state,
        policy=lambda state: jnp.full((5, 2), 0.5), needs_plan=lambda state: jnp.zeros((), bool),
        plan=lambda key, state: FirstKeyState(state.plans + 1, jnp.where(state.plans == 0, jax.random.key_data(key),
                                                                         state.first_key)),
    )
    assert agent.plans and not agents.get("q_learning_continuous").plans
    g = runner.product([river_swim(False)], [ScriptedHParams()], seeds=[0, 1])
    res = runner.run(agent, g, 30, log_period=10, n_records=1)
    np.testing.assert_array_equal(res.agent_state.plans, [1, 1])
    for b in range(2):
        sub = jax.random.split(jax.random.wrap_key_data(jnp.asarray(g.key_data[b])), 4)
        np.testing.assert_array_equal(res.agent_state.first_key[b], jax.random.key_data(jax.random.fold_in(sub[3], 2)))


def test_a_shard_above_the_agents_whole_batch_limits_compiles_one_copy_of_plan_with_the_same_results():
    # Six members asking every 3, 4 or 6 updates: at c = 6 four ask and at c = 12 all six, more than half, which a
    # shard of at most whole_batch_plans members plans whole. Above it, rounds only: plan is traced once per chunk
    # program instead of twice (whole batch and rounds), and the records and plan counts are the same.
    traced = []

    def counting(limit, nbytes=None):
        def plan(key, state):
            traced.append((limit, nbytes))
            return SCRIPTED[False].plan(key, state)

        return dataclasses.replace(SCRIPTED[False], name=f"scripted_{limit}_{nbytes}", plan=plan).with_hints(
            whole_batch_plans=limit, whole_batch_bytes=nbytes)

    g = runner.product([river_swim(False)], [ScriptedHParams(3), ScriptedHParams(4), ScriptedHParams(6)], seeds=[0, 1])
    # Whole: at most 6 members and no byte bound. Rounds: 5 members, or 6 members above a byte bound of 1 byte.
    limits = [(6, None), (5, None), (6, 1)]
    whole, rounds, by_bytes = (runner.run(counting(*lim), g, 60, log_period=10, n_records=2, shards=1)
                               for lim in limits)
    once = traced.count(limits[1])
    assert once >= 1 and traced.count(limits[0]) == 2 * once and traced.count(limits[2]) == once
    for res in (rounds, by_bytes):
        np.testing.assert_array_equal(res.values, whole.values)
        np.testing.assert_array_equal(res.agent_state.plans, whole.agent_state.plans)
    # The first plan, then one before every step at which c is a positive multiple (c = 60 is after the last step).
    np.testing.assert_array_equal(whole.agent_state.plans, 1 + 59 // np.array([3, 3, 4, 4, 6, 6]))


def test_a_small_batch_plans_whole_with_one_copy_of_plan_and_the_same_results():
    # Four members (at most lockstep.SMALL_BATCH) asking every 3 or 4 updates: by default a slot per member, so every
    # plan is the whole batch's and plan is traced once per chunk program; with one slot (rounds, and the whole batch
    # when more than half ask) it is traced twice. The records and plan counts are the same.
    traced = []

    def counting(tag):
        def plan(key, state):
            traced.append(tag)
            return SCRIPTED[False].plan(key, state)

        return dataclasses.replace(SCRIPTED[False], name=f"scripted_small_{tag}", plan=plan)

    g = runner.product([river_swim(False)], [ScriptedHParams(3), ScriptedHParams(4)], seeds=[0, 1])
    assert g.n_members <= lockstep.SMALL_BATCH
    default = runner.run(counting("default"), g, 60, log_period=10, n_records=2, shards=1)
    one_slot = runner.run(counting("one slot"), g, 60, log_period=10, n_records=2, shards=1, plan_slots=1)
    once = traced.count("default")
    assert once >= 1 and traced.count("one slot") == 2 * once
    np.testing.assert_array_equal(one_slot.values, default.values)
    np.testing.assert_array_equal(one_slot.agent_state.plans, default.agent_state.plans)
    np.testing.assert_array_equal(default.agent_state.plans, 1 + 59 // np.array([3, 3, 4, 4]))
    # Above SMALL_BATCH, or for an agent that may not plan whole, the default stays ceil(B / 16) slots.
    states = jax.vmap(lambda k: SCRIPTED[False].init(k, spec_of(river_swim(False), 10), ScriptedHParams()))(
        jax.random.split(jax.random.key(0), lockstep.SMALL_BATCH + 1))
    assert lockstep.plan_slots_for(SCRIPTED[False], states) == 1
    small = jax.tree.map(lambda x: x[:lockstep.SMALL_BATCH], states)
    assert lockstep.plan_slots_for(SCRIPTED[False], small) == lockstep.SMALL_BATCH
    assert lockstep.plan_slots_for(SCRIPTED[False].with_hints(whole_batch_plans=0), small) == 1


def test_the_whole_batch_bytes_bound_the_agent_states_of_a_shard():
    # The scripted agent's state for two members is some hundred bytes: a bound at or above it plans whole, one
    # byte below it plans in rounds, as does a member bound below two members.
    states = jax.vmap(lambda k: SCRIPTED[False].init(k, spec_of(river_swim(False), 10), ScriptedHParams()))(
        jax.random.split(jax.random.key(0), 2))
    size = sum(np.asarray(x).nbytes for x in jax.tree.leaves(states))  # numpy's count, on the host
    agent = lambda **kw: SCRIPTED[False].with_hints(**kw)  # noqa: E731
    assert plans_whole(agent(), states) and plans_whole(agent(whole_batch_bytes=size), states)
    assert not plans_whole(agent(whole_batch_bytes=size - 1), states)
    assert not plans_whole(agent(whole_batch_bytes=size, whole_batch_plans=1), states)
    assert plans_whole(agent(whole_batch_bytes=size, whole_batch_plans=2), states)


@pytest.mark.parametrize("field", ["whole_batch_plans", "whole_batch_bytes", "plan_slot_bytes"])
def test_a_bad_planning_limit_is_refused_before_compiling(field):
    g = runner.product([river_swim(False)], [ScriptedHParams()], seeds=[0])
    for bad in (-1, 2.5, "64", True):
        agent = SCRIPTED[False].with_hints(**{field: bad})
        with pytest.raises(ValueError, match=rf"RunnerHints.{field} must be an integer >= 0 or None \(agent "):
            runner.run(agent, g, 10)


def test_exact_mode_logs_every_step():
    mdp = river_swim(False)
    g = runner.product([mdp], [ScriptedHParams(), ScriptedHParams(plan_every=7)], seeds=[0])
    # 201 steps: the last policy differs from the first, so charging each step to the wrong policy would show.
    res = runner.run(SCRIPTED[False], g, 201, log_period=1, n_records=3)
    np.testing.assert_array_equal(res.steps, [67, 134, 201])
    want = expected_accounting(mdp, 201, 1)[res.steps]
    np.testing.assert_allclose(res.values[:, 0], want, rtol=1e-5, atol=1e-4)


def test_record_steps():
    assert runner.record_steps(1050, 100, 4)[0] == 300
    np.testing.assert_array_equal(runner.record_steps(1050, 100, 4)[1], [300, 600, 900, 1050])
    np.testing.assert_array_equal(runner.record_steps(500_000, 100, 100)[1], np.arange(5000, 500_001, 5000))
    np.testing.assert_array_equal(runner.record_steps(7, 100, 100)[1], [7])
    np.testing.assert_array_equal(runner.record_steps(10, 1, 100)[1], np.arange(1, 11))


# ---------------------------------------------------------------------------------------------------------------
# The random agent's expected regret is the random baseline
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("episodic", [pytest.param(False, marks=pytest.mark.nightly), True])
def test_random_agent_regret_is_the_random_baseline(episodic):
    # p_rand makes every policy ergodic, so the uniform policy's gain does not depend on the current state.
    mdp = river_swim(episodic, p_rand=0.1, make_reward_stochastic=True)
    agent = agents.get("random_episodic" if episodic else "random_continuous")
    res = runner.run(agent, runner.product([mdp], [agent.default_hparams], seeds=[0, 1]), 1000, n_records=5)
    for ours, baseline in [
        ("cumulative_regret", "random_cumulative_regret"),
        ("normalized_cumulative_regret", "random_normalized_cumulative_regret"),
        ("cumulative_expected_reward", "random_cumulative_expected_reward"),
        ("normalized_cumulative_expected_reward", "random_normalized_cumulative_expected_reward"),
    ]:
        np.testing.assert_allclose(res.column(ours), res.column(baseline), rtol=2e-5, err_msg=ours)
    assert np.all(res.column("random_cumulative_regret") > 0)
    # The sampled reward: the sum of the very rewards that a replay of each member's key stream draws (float64 sum).
    for member, key_data in enumerate(runner.product([mdp], [agent.default_hparams], seeds=[0, 1]).key_data):
        want = np.cumsum(replay_rewards(agent, mdp, key_data, 1000).astype(np.float64))[res.steps - 1]
        np.testing.assert_allclose(res.values[:, member, 1], want, rtol=1e-6, atol=1e-6)


def replay_rewards(agent, mdp, key_data, n_steps):
    """The rewards of one member of an agent that never plans, replayed step by step from its key as the runner's
    key stream is laid out: ``sub = split(key, 4)``; reset and init with ``fold_in(sub[3], 0 | 1)``; step ``t``
    draws the environment from ``fold_in(sub[0], t)`` and the action from ``fold_in(sub[1], t)``."""
    from jaxmdp.experiment.agent_interface import Transition, spec_of

    sub = jax.random.split(jax.random.wrap_key_data(jnp.asarray(key_data)), 4)
    obs, env_state = jaxmdp.reset(jax.random.fold_in(sub[3], 0), mdp)
    state = agent.init(jax.random.fold_in(sub[3], 1), spec_of(mdp, n_steps), agent.default_hparams)

    def body(carry, t):
        obs, env_state, state = carry
        needs_plan = agent.needs_plan(state)
        action = agent.act(jax.random.fold_in(sub[1], t), state, obs, env_state.h)
        k_env = jax.random.fold_in(sub[0], t)
        obs2, env_state2, reward, terminated, _, info = jaxmdp.step(k_env, env_state, action, mdp)
        tr = Transition(obs=obs, action=action, reward=reward, next_obs=info["final_observation"], h=env_state.h,
                        terminated=terminated)
        return (obs2, env_state2, agent.update(state, tr)), (reward, needs_plan)

    _, (rewards, plans) = jax.jit(lambda c: jax.lax.scan(body, c, jnp.arange(n_steps)))((obs, env_state, state))
    assert not np.any(np.asarray(plans))
    return np.asarray(rewards)


# ---------------------------------------------------------------------------------------------------------------
# Batching, determinism, chunking and resume
# ---------------------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def two_mdps():
    small = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4, randomize_actions=False, p_lazy=0.2,
                        make_reward_stochastic=True)
    big = river_swim(False, p_lazy=0.1, make_reward_stochastic=True)
    return small, big


@pytest.mark.nightly  # the default profile: tests/test_properties_* (a member alone and in a batch of others)
def test_vmapped_grid_equals_single_runs(two_mdps):
    agent = agents.get("q_learning_continuous")
    hps = [agent.default_hparams, agent.default_hparams.replace(h_weight=0.5)]
    keys = jax.random.split(jax.random.key(7), 2)
    g = runner.grid(list(two_mdps), runner.stack_hparams(hps), keys)
    batch = runner.run(agent, g, 600, n_records=3)
    for b in range(2):
        single = runner.grid(two_mdps[b], runner.stack_hparams([hps[b]]), keys[b:b + 1])
        one = runner.run(agent, single, 600, n_records=3)
        np.testing.assert_allclose(batch.values[:, b], one.values[:, 0], rtol=1e-6, atol=1e-6)
        S = two_mdps[b].n_states
        np.testing.assert_allclose(batch.agent_state.Q_hat[b, :S], one.agent_state.Q_hat[0], rtol=1e-6)


def test_same_key_same_result_and_keys_matter(two_mdps):
    agent = agents.get("q_learning_continuous")
    g = runner.product([two_mdps[1]], [agent.default_hparams], seeds=[0, 1])
    a = runner.run(agent, g, 600, n_records=3)
    b = runner.run(agent, g, 600, n_records=3)
    np.testing.assert_array_equal(a.values, b.values)
    assert not np.array_equal(a.values[:, 0, 1], a.values[:, 1, 1])  # different seeds, different rewards


def test_chunking_and_resume_do_not_change_results(two_mdps, tmp_path):
    agent = agents.get("q_learning_continuous")
    g = runner.product([two_mdps[1]], [agent.default_hparams], seeds=[0, 1])
    whole = runner.run(agent, g, 1000, n_records=10, csv_path=tmp_path / "whole.csv")
    ckpt, path = tmp_path / "run.npz", tmp_path / "parts.csv"
    part = runner.run(agent, g, 1000, n_records=10, chunk_steps=150, csv_path=path, checkpoint_path=ckpt,
                      stop_after_chunks=3)
    assert part.steps[-1] == 400 and ckpt.exists()
    # A crash after rows were written but before the checkpoint: a stale row must be dropped on resume.
    with open(path, "a") as f:
        f.write(",".join(["0", "x", "0", "0", "500"] + ["0"] * (len(CSV_COLUMNS) - 1)) + "\n")
    rest = runner.run(agent, g, 1000, n_records=10, chunk_steps=150, csv_path=path, checkpoint_path=ckpt)
    np.testing.assert_array_equal(rest.steps, whole.steps)
    np.testing.assert_array_equal(rest.values, whole.values)
    np.testing.assert_array_equal(rest.agent_state.Q, whole.agent_state.Q)

    def read(p):
        with open(p, newline="") as f:
            rows = list(csv.reader(f))
        return [r[:-1] for r in rows]  # steps_per_second differs

    assert read(path) == read(tmp_path / "whole.csv")
    assert read(path)[0] == list(runner.MEMBER_COLUMNS + CSV_COLUMNS[:-1])
    assert len(read(path)) == 1 + 10 * 2


def test_checkpoint_of_another_run_is_refused(two_mdps, tmp_path):
    agent = agents.get("q_learning_continuous")
    g = runner.product([two_mdps[1]], [agent.default_hparams], seeds=[0, 1])
    ckpt = tmp_path / "run.npz"
    runner.run(agent, g, 600, n_records=3, chunk_steps=200, checkpoint_path=ckpt, stop_after_chunks=1)
    g2 = runner.product([two_mdps[1]], [agent.default_hparams], seeds=[3, 4])
    with pytest.raises(ValueError, match="different run"):
        runner.run(agent, g2, 600, n_records=3, chunk_steps=200, checkpoint_path=ckpt)


def test_product_layout():
    agent = agents.get("q_learning_continuous")
    mdps = [river_swim(False), river_swim(False, p_lazy=0.5)]
    hps = [agent.default_hparams, agent.default_hparams.replace(min_at=0.0)]
    g = runner.product(mdps, hps, seeds=[3, 4, 5])
    assert g.n_members == 12
    np.testing.assert_array_equal(g.mdp_index, np.repeat([0, 1], 6))
    np.testing.assert_array_equal(g.hparams_index, np.tile(np.repeat([0, 1], 3), 2))
    np.testing.assert_array_equal(g.seeds, np.tile([3, 4, 5], 4))
    np.testing.assert_allclose(g.hparams.min_at, np.tile(np.repeat([0.073, 0.0], 3), 2), rtol=1e-6)
    np.testing.assert_array_equal(g.key_data[4], jax.random.key_data(jax.random.key(4)))
    assert g.mdps.T.shape[0] == 2  # distinct MDPs are stored once


def test_grid_take_selects_members_in_order():
    agent = agents.get("q_learning_continuous")
    hps = [agent.default_hparams, agent.default_hparams.replace(min_at=0.0)]
    g = runner.product([river_swim(False), river_swim(False, p_lazy=0.5)], hps, seeds=[3, 4, 5])
    picked = [11, 0, 0, 7]
    t = g.take(picked)
    assert t.n_members == 4 and t.mdps is g.mdps and t.mdp_labels == g.mdp_labels
    for field in ("mdp_index", "key_data", "hparams_index", "seeds"):
        np.testing.assert_array_equal(getattr(t, field), np.asarray(getattr(g, field))[picked])
    np.testing.assert_array_equal(t.hparams.min_at, np.asarray(g.hparams.min_at)[picked])
    np.testing.assert_array_equal(runner.take_members({"t": np.int32(7), "x": np.arange(12)}, slice(3))["x"],
                                  [0, 1, 2])
    for bad in ([12], [-1], [[0, 1]], [0.5]):
        with pytest.raises(ValueError, match=r"members must be a 1-D sequence of member indices in \[0, 12\)"):
            g.take(bad)


# ---------------------------------------------------------------------------------------------------------------
# Bad input: clear errors before anything compiles
# ---------------------------------------------------------------------------------------------------------------


def _grid(episodic=False, hparams=None):
    agent = agents.get("q_learning_episodic" if episodic else "q_learning_continuous")
    return runner.product([river_swim(episodic)], [hparams or agent.default_hparams], seeds=[0])


def test_episodic_agent_on_continuous_mdp_and_reverse():
    with pytest.raises(ValueError, match="episodic.*continuous"):
        runner.run(agents.get("q_learning_episodic"), _grid(False), 100)
    with pytest.raises(ValueError, match="continuous.*episodic"):
        runner.run(agents.get("q_learning_continuous"), _grid(True), 100)


@pytest.mark.parametrize("kw, match", [
    ({"n_steps": 0}, "n_steps"),
    ({"n_steps": -5}, "n_steps"),
    ({"n_steps": 10.5}, "n_steps"),
    ({"log_period": 0}, "log_period"),
    ({"n_records": 0}, "n_records"),
    ({"chunk_steps": 0}, "chunk_steps"),
    ({"variant": "gym"}, "variant"),
])
def test_bad_settings(kw, match):
    args = {"n_steps": 100, **kw}
    with pytest.raises(ValueError, match=match):
        runner.run(agents.get("q_learning_continuous"), _grid(False), **args)


def test_hparams_outside_domain():
    agent = agents.get("q_learning_continuous")
    with pytest.raises(ValueError, match="min_at"):
        runner.run(agent, _grid(False, agent.default_hparams.replace(min_at=1.5)), 100)
    ep = agents.get("q_learning_episodic")
    with pytest.raises(ValueError, match="p must"):
        runner.run(ep, _grid(True, ep.default_hparams.replace(p=0.0)), 100)


def test_agent_that_does_not_fit_the_mdp():
    # An agent built for 3 states facing a 5-state MDP.
    base = agents.get("random_continuous")
    wrong = Agent(name="fixed_size", episodic=False, default_hparams=base.default_hparams, init=base.init,
                  act=base.act, update=base.update, policy=lambda state: jnp.full((3, 2), 0.5))
    with pytest.raises(ValueError, match="S=5"):
        runner.run(wrong, runner.product([river_swim(False)], [base.default_hparams], seeds=[0]), 100)


def test_grid_errors():
    agent = agents.get("q_learning_continuous")
    mdps = [river_swim(False), river_swim(False, p_lazy=0.5)]
    with pytest.raises(ValueError, match="seeds"):
        runner.product(mdps, [agent.default_hparams], seeds=[-1])
    with pytest.raises(ValueError, match="hparams"):
        runner.product(mdps, [], seeds=[0])
    hp = runner.stack_hparams([agent.default_hparams] * 3)
    with pytest.raises(ValueError, match="mdp_index"):
        runner.grid(mdps, hp, jax.random.split(jax.random.key(0), 3))
    with pytest.raises(ValueError, match="keys"):
        runner.grid(mdps[0], hp, jax.random.split(jax.random.key(0), 2))
    with pytest.raises(ValueError, match="episodic"):
        runner.product([river_swim(False), river_swim(True)], [agent.default_hparams], seeds=[0])


def test_colosseum_episodic_variant_uses_the_latest_episode_start():
    # Two equally likely start states whose regrets differ. The expected numbers replay the runner's documented key
    # schedule (member key split in 4: environment, actions, planning, initialisation; step t uses
    # fold_in(environment key, t)) with jaxmdp.step, and track the start state of each step's episode.
    T = np.zeros((3, 2, 3))
    T[:, 0, 2] = 1.0  # action 0 -> state 2
    T[:, 1, 0] = 1.0  # action 1 -> state 0
    R = np.array([[0.0, 1.0], [0.2, 0.0], [0.5, 0.1]])
    H = 2
    mdp = jaxmdp.custom_mdp(T, R=R, P0=[0.5, 0.5, 0.0], H=H)
    agent = SCRIPTED[True]
    n_steps, period = 50, 3
    res = runner.run(agent, runner.product([mdp], [ScriptedHParams()], seeds=[11]), n_steps, log_period=period,
                     n_records=n_steps, variant="colosseum")
    paper = runner.run(agent, runner.product([mdp], [ScriptedHParams()], seeds=[11]), n_steps, log_period=period,
                       n_records=n_steps)

    v_opt, v_min = finite_horizon_optimal(T, R, H), finite_horizon_optimal(T, R, H, -1.0)
    sub = jax.random.split(jax.random.key(11), 4)
    step = jax.jit(jaxmdp.step)
    obs, st = jaxmdp.reset(jax.random.fold_in(sub[3], 0), mdp)
    start, acc, last, starts_seen = int(obs), np.zeros(2), 0, set()
    want = {}
    for t in range(n_steps):
        a = scripted_action(t, 2)
        obs, st, _, term, _, _ = step(jax.random.fold_in(sub[0], t), st, a, mdp)
        s0 = start
        if bool(term):
            start = int(obs)
        c = t + 1
        if c % period == 0 or c == n_steps:
            v = finite_horizon_eval(T, R, one_hot(np.full(3, scripted_action(c, 2)), 2), H)
            gap = max(v_opt[s0] - v[s0], 0.0)
            acc += np.array([gap / H, gap / (v_opt[s0] - v_min[s0])]) * (c - last)
            last = c
            starts_seen.add(s0)
        want[c] = acc.copy()
    assert starts_seen == {0, 1}
    got = res.values[:, 0][:, [0, 3]]
    np.testing.assert_allclose(got, np.array([want[int(c)] for c in res.steps]), rtol=1e-5, atol=1e-5)
    assert not np.allclose(got, paper.values[:, 0][:, [0, 3]], atol=1e-3)


def test_mdp_labels_are_unambiguous():
    custom = [jaxmdp.custom_mdp(np.full((2, 2, 2), 0.5), R=np.eye(2) * r) for r in (0.1, 0.2)]
    assert runner.product(custom, [ScriptedHParams()], seeds=[0]).mdp_labels == ("custom#0", "custom#1")
    labels = runner.product([river_swim(False), river_swim(False, p_lazy=0.5)], [ScriptedHParams()], [0]).mdp_labels
    assert len(set(labels)) == 2 and "p_lazy=0.5" in labels[1]


def test_not_an_agent_or_grid():
    g = runner.product([river_swim(False)], [ScriptedHParams()], seeds=[0])
    with pytest.raises(ValueError, match="Agent"):
        runner.run("q_learning", g, 10)
    with pytest.raises(ValueError, match="Grid"):
        runner.run(SCRIPTED[False], [river_swim(False)], 10)
    with pytest.raises(ValueError, match="shards"):
        runner.run(SCRIPTED[False], g, 10, shards=2)


def scripted_visits(mdp, n_steps):
    """numpy: the states the scripted agent acts in on a deterministic MDP, counted."""
    T, P0 = np.asarray(mdp.T, np.float64), np.asarray(mdp.P0, np.float64)
    counts = np.zeros(mdp.n_states, np.int64)
    s, h = int(np.argmax(P0)), 0
    for t in range(n_steps):
        counts[s] += 1
        s, h = int(np.argmax(T[s, scripted_action(t, T.shape[1])])), h + 1
        if mdp.episodic and h == mdp.H:
            s, h = int(np.argmax(P0)), 0
    return counts


@pytest.mark.parametrize("episodic", [False, True])
def test_record_visits_counts_the_states_acted_in(episodic, tmp_path):
    mdp = river_swim(episodic)
    agent = SCRIPTED[episodic]
    g = runner.product([mdp], [agent.default_hparams], seeds=[0, 1])
    n = 257
    res = runner.run(agent, g, n, n_records=4, record_visits=True)
    assert res.visits.shape == (2, mdp.n_states)
    expected = scripted_visits(mdp, n)
    np.testing.assert_array_equal(res.visits, np.stack([expected, expected]))
    # Chunked and resumed from a checkpoint, the counts are the same; without the option there are none and the
    # records are unchanged.
    ckpt = tmp_path / "v.npz"
    runner.run(agent, g, n, n_records=4, chunk_steps=60, checkpoint_path=ckpt, stop_after_chunks=2,
               record_visits=True)
    resumed = runner.run(agent, g, n, n_records=4, chunk_steps=60, checkpoint_path=ckpt, record_visits=True)
    np.testing.assert_array_equal(resumed.visits, res.visits)
    plain = runner.run(agent, g, n, n_records=4)
    assert plain.visits is None
    np.testing.assert_array_equal(plain.values, res.values)


@pytest.mark.nightly  # by default: test_record_visits_counts_the_states_acted_in
def test_record_visits_random_agent_sums_to_steps():
    agent = agents.RANDOM_CONTINUOUS
    mdp = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, p_rand=0.2)
    g = runner.product([mdp], [agent.default_hparams], seeds=[0, 1, 2])
    res = runner.run(agent, g, 300, n_records=2, record_visits=True)
    np.testing.assert_array_equal(res.visits.sum(1), [300, 300, 300])
    assert not np.array_equal(res.visits[0], res.visits[1])  # seeds differ


def test_only_changed_members_are_evaluated():
    # Members whose policy changed get fresh policy values (the gain from every state), the others keep their cache.
    from jaxmdp.experiment.indicators import policy_values

    rng = np.random.default_rng(4)
    mdps = jaxmdp.stack([random_mdp(rng, S=4, A=2), random_mdp(rng, S=3, A=2)]).strip()
    policy = jnp.asarray(rng.dirichlet(np.ones(2), size=(3, 4)), jnp.float32)
    index = jnp.asarray([0, 1, 0])
    cache = jnp.full((3, 4), 7.0, jnp.float32)
    out = jax.jit(runner._evaluate_changed)(mdps, index, policy, jnp.asarray([True, False, True]), cache)
    for b in (0, 2):
        want = policy_values(jax.tree.map(lambda x: x[0], mdps), policy[b])
        np.testing.assert_allclose(out[b], want, rtol=1e-6, atol=1e-7)
    np.testing.assert_array_equal(out[1], cache[1])


@pytest.mark.parametrize("name", ["q_learning_episodic", pytest.param("q_learning_continuous", marks=pytest.mark.nightly)])
def test_greedy_action_indices_give_the_same_records_as_the_one_hot_policy(name):
    # The runner compares and evaluates an agent's greedy_actions where it has them; without them (the one-hot
    # policy, as every agent before) every record is bit-identical, on a stacked grid of two MDPs of different sizes
    # and horizons (padded states and actions, a traced horizon below H).
    agent = agents.get(name)
    assert agent.hints.greedy_actions is not None
    episodic = agent.episodic
    rng = np.random.default_rng(11)
    mdps = [random_mdp(rng, S=5, A=3, H=4 if episodic else None), random_mdp(rng, S=3, A=2, H=6 if episodic else None)]
    g = runner.product(mdps, [agent.default_hparams], seeds=[0, 1, 2])
    indices = runner.run(agent, g, 500, log_period=7, n_records=5)
    one_hot = agent.with_hints(greedy_actions=None)
    probabilities = runner.run(one_hot, g, 500, log_period=7, n_records=5)
    np.testing.assert_array_equal(indices.values, probabilities.values)
    assert np.all(indices.values[-1, :, 0] > 0)  # some regret: the policies were evaluated, not all optimal


@pytest.mark.nightly  # by default: test_a_policy_declared_fixed_is_evaluated_at_the_first_log_only
@pytest.mark.parametrize("name", ["random_episodic", pytest.param("random_continuous", marks=pytest.mark.nightly)])
def test_a_fixed_policy_gives_the_same_records_evaluated_once(name, tmp_path):
    # The random agent declares its policy fixed: the runner evaluates it at the first log and never extracts or
    # compares it again. Every record is bit-identical to the comparing runner's, on a stacked grid of two MDPs of
    # different sizes, also when the run stops after two chunks and resumes from its checkpoint.
    agent = agents.get(name)
    assert agent.hints.fixed_policy
    rng = np.random.default_rng(12)
    H = (4, 6) if agent.episodic else (None, None)
    mdps = [random_mdp(rng, S=5, A=3, H=H[0]), random_mdp(rng, S=3, A=2, H=H[1])]
    g = runner.product(mdps, [agent.default_hparams], seeds=[0, 1])
    comparing = runner.run(agent.with_hints(fixed_policy=False), g, 300, log_period=7, n_records=6)
    ckpt = tmp_path / "run.npz"
    part = runner.run(agent, g, 300, log_period=7, n_records=6, chunk_steps=50, checkpoint_path=ckpt,
                      stop_after_chunks=2)
    assert part.steps[-1] < 300 and ckpt.exists()
    fixed = runner.run(agent, g, 300, log_period=7, n_records=6, chunk_steps=50, checkpoint_path=ckpt)
    np.testing.assert_array_equal(fixed.steps, comparing.steps)
    np.testing.assert_array_equal(fixed.values, comparing.values)
    assert np.all(fixed.values[-1, :, 0] > 0)


def test_a_policy_declared_fixed_is_evaluated_at_the_first_log_only():
    # Q-learning's policy changes, but declared fixed it is evaluated once: every log adds the first log's regret
    # per step, so the cumulative regret grows linearly from the first log on (the comparing runner's does not).
    base = agents.get("q_learning_continuous")
    g = runner.product([river_swim(False, p_rand=0.1)], [base.default_hparams], seeds=[0])
    fixed = runner.run(base.with_hints(fixed_policy=True), g, 1000, log_period=10, n_records=10)
    changing = runner.run(base, g, 1000, log_period=10, n_records=10)
    for res, linear in ((fixed, True), (changing, False)):
        rate = res.values[:, 0, 0] / res.steps
        assert np.allclose(rate, rate[0], rtol=1e-5) == linear


def test_greedy_actions_of_the_wrong_shape_are_refused():
    base = agents.get("q_learning_continuous")
    wrong = base.with_hints(greedy_actions=lambda state: jnp.zeros((2,), jnp.int32))
    with pytest.raises(ValueError, match="greedy_actions"):
        runner.run(wrong, runner.product([river_swim(False)], [base.default_hparams], seeds=[0]), 100)


def test_each_log_gets_the_warm_start_the_previous_log_returned():
    # A warm policy that plays constant action start % A and returns start + 1: log k (from 1) evaluates action
    # (k - 1) % A. The same records as a plain policy that reads k from the update count; a runner that kept the first
    # start would evaluate action 0 at every log.
    period, n_steps = 7, 70

    def warm_policy(state, start):
        return jax.nn.one_hot(jnp.full((state.n_states,), start[0] % state.n_actions), state.n_actions), start + 1

    def by_count(state):
        return jax.nn.one_hot(jnp.full((state.n_states,), (state.c // period - 1) % state.n_actions), state.n_actions)

    base = SCRIPTED[False]
    warm = dataclasses.replace(base, name="scripted_warm").with_hints(
        warm_policy=warm_policy, policy_start=lambda state: jnp.zeros((1,), jnp.int32))
    plain = dataclasses.replace(base, name="scripted_by_count", policy=by_count)
    g = runner.product([river_swim(False)], [ScriptedHParams(plan_every=1000)], seeds=[0, 1])
    got, want = (runner.run(a, g, n_steps, log_period=period, n_records=10) for a in (warm, plain))
    for column in ("cumulative_regret", "normalized_cumulative_regret", "cumulative_expected_reward"):
        np.testing.assert_array_equal(got.column(column), want.column(column))
    assert len(np.unique(np.diff(np.asarray(want.column("cumulative_regret"))[:, 0]))) > 1  # the actions differ


@pytest.mark.parametrize("fields", [dict(warm_policy=lambda s, u: (None, u)), dict(policy_start=lambda s: None)])
def test_warm_policy_and_policy_start_go_together(fields):
    with pytest.raises(ValueError, match="warm_policy and policy_start go together"):
        SCRIPTED[False].with_hints(**fields)
    both = dict(warm_policy=lambda s, u: (None, u), policy_start=lambda s: None)
    with pytest.raises(ValueError, match="warm_policy is for agents without greedy_actions"):
        agents.get("q_learning_continuous").with_hints(**both)


@pytest.mark.parametrize("returned, match", [
    (lambda state, start: (jnp.zeros((state.n_states,)), start), "returns a warm_policy of"),
    (lambda state, start: (jax.nn.one_hot(jnp.zeros((state.n_states,), int), state.n_actions), start[:1] * 1.0),
     "warm_policy returns a start of"),
])
def test_a_warm_policy_that_does_not_fit_is_refused_before_compiling(returned, match):
    agent = dataclasses.replace(SCRIPTED[False], name="scripted_bad_warm").with_hints(
        warm_policy=returned, policy_start=lambda state: jnp.zeros((2,), jnp.int32))
    g = runner.product([river_swim(False)], [ScriptedHParams()], seeds=[0])
    with pytest.raises(ValueError, match=match):
        runner.run(agent, g, 10, log_period=5)



# ---------------------------------------------------------------------------------------------------------------
# The reference's convergence stop (run(..., stop_when_converged=True), docs/measures.md §6.4)
# ---------------------------------------------------------------------------------------------------------------


class SwitchHParams(struct.PyTreeNode):
    switch_at: int | jax.Array = 500  # updates after which the agent turns LEFT (0: from the start)


class SwitchState(struct.PyTreeNode):
    c: jax.Array
    plans: jax.Array
    switch_at: jax.Array


def _switch_action(state):
    return jnp.where(state.c < state.switch_at, 1, 0).astype(jnp.int32)  # RiverSwim: 1 = RIGHT, optimal


SWITCH = Agent(
    name="switch_right_then_left", episodic=False, default_hparams=SwitchHParams(),
    init=lambda key, spec, hp: SwitchState(jnp.int32(0), jnp.int32(0), jnp.asarray(hp.switch_at, jnp.int32)),
    act=lambda key, state, obs, h: _switch_action(state),
    update=lambda state, tr: state.replace(c=state.c + 1),
    policy=lambda state: jnp.broadcast_to(jax.nn.one_hot(_switch_action(state), 2), (5, 2)),
    needs_plan=lambda state: (state.c > 0) & (state.c % 7 == 0),
    plan=lambda key, state: state.replace(plans=state.plans + 1),
)


def test_the_reference_s_convergence_stop_freezes_a_member_whose_regret_stayed_at_zero(tmp_path):
    # Continuous RiverSwim 5: RIGHT everywhere has regret 0, LEFT 0.995 (normalised). Member 0 goes RIGHT for its first
    # 500 updates, then LEFT; member 1 LEFT from the start. Logs every 10 of 1 000 steps. With the stop, member 0's
    # regret has been 0 at ten logs in a row at the first log past a fifth of the run, t = 210 (t = 200 is not past
    # it): it stops learning there, so it keeps c = 210 and goes RIGHT to the end (cumulative regret 0), and plans no
    # more (its plans: before the first action, then at c = 7, 14, ..., 203: 30). Member 1 never stops. Without the
    # stop, member 0 turns LEFT after 500 updates.
    g = runner.product([river_swim(False)], [SwitchHParams(500), SwitchHParams(0)], seeds=[0])
    stop = runner.run(SWITCH, g, 1000, log_period=10, n_records=10, stop_when_converged=True)
    np.testing.assert_array_equal(stop.stopped_at, [210, 0])
    np.testing.assert_array_equal(stop.agent_state.c, [210, 1000])
    np.testing.assert_array_equal(stop.agent_state.plans, [30, 1 + 998 // 7])
    normalized = stop.column("normalized_cumulative_regret")
    assert normalized[-1, 0] == 0.0
    np.testing.assert_allclose(normalized[-1, 1], 0.995 * 1000, rtol=1e-5)
    # It also acts with the state it stopped with: its sampled rewards are those of the agent that never turns.
    g_right = runner.product([river_swim(False)], [SwitchHParams(10**6), SwitchHParams(0)], seeds=[0])
    right = runner.run(SWITCH, g_right, 1000, log_period=10, n_records=10)
    np.testing.assert_array_equal(stop.column("cumulative_reward")[:, 0], right.column("cumulative_reward")[:, 0])
    free = runner.run(SWITCH, g, 1000, log_period=10, n_records=10)
    assert free.stopped_at is None
    np.testing.assert_array_equal(free.agent_state.c, [1000, 1000])
    # LEFT from the log after update 500 on, each log charging the ten steps before it: 51 logs.
    np.testing.assert_allclose(free.column("normalized_cumulative_regret")[-1, 0], 0.995 * 510, rtol=1e-5)
    np.testing.assert_array_equal(free.values[:, 1], stop.values[:, 1])  # member 1 alike either way
    # A member stops only after ten logs at 0: with logs every 100 steps there are two past a fifth of the run (at
    # 300 and 400) before member 0 turns, and then its regret is 0.995: no stop.
    sparse = runner.run(SWITCH, g, 1000, log_period=100, n_records=10, stop_when_converged=True)
    np.testing.assert_array_equal(sparse.stopped_at, [0, 0])
    # Interrupted and resumed: the same run (the checkpoint carries the window and the stop).
    ckpt = tmp_path / "stop.npz"
    part = runner.run(SWITCH, g, 1000, log_period=10, n_records=10, stop_when_converged=True, chunk_steps=100,
                      checkpoint_path=ckpt, stop_after_chunks=3)
    assert part.steps[-1] == 300
    resumed = runner.run(SWITCH, g, 1000, log_period=10, n_records=10, stop_when_converged=True, chunk_steps=100,
                         checkpoint_path=ckpt)
    np.testing.assert_array_equal(resumed.stopped_at, [210, 0])
    np.testing.assert_array_equal(resumed.values, stop.values)
    with pytest.raises(ValueError, match="stop_when_converged must be True or False; got 1"):
        runner.run(SWITCH, g, 100, stop_when_converged=1)


def test_the_program_caches_hold_one_shape_per_entry_and_free_what_they_evict():
    # A long benchmark run meets many shapes in one process. Each compiled CPU program holds thousands of memory maps
    # (Linux bounds them, vm.max_map_count); one cached jitted function per agent kept a program for every shape, and
    # a run aborted compiling its 24th part. Keyed by the inputs' shapes, an entry is one shape's program and evicting
    # it frees its maps. Mutation: without the signature in the initialisation program's key, the second shape hits
    # the first's entry.
    from conftest import memory_maps
    from jaxmdp.experiment import programs

    caches = (programs.init_program, programs.chunk_program, programs.constants_program)
    for cache in caches:
        assert cache.cache_info().maxsize == programs.MAX_CACHED_PROGRAMS
        cache.cache_clear()
    agent = agents.get("random_continuous")
    for S in (3, 4, 3):
        mdp = random_mdp(np.random.default_rng(S), S=S, A=2)
        runner.run(agent, runner.product([mdp], [agent.default_hparams], [0]), 20, log_period=10, n_records=2)
    for cache in caches:
        info = cache.cache_info()
        assert (info.misses, info.hits, info.currsize) == (2, 1, 2)
    before = memory_maps()
    for cache in caches:
        cache.cache_clear()
    gc.collect()
    if before is not None:  # two shapes' three programs hold about 1 000 maps or more (Linux)
        freed = before - memory_maps()
        assert freed > 500, freed
