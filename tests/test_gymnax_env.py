"""jaxmdp.as_gymnax: a gymnax Environment whose transitions and rewards are jaxmdp.step's, with gymnax's spaces,
auto-reset and wrappers, and a PPO (the notebook's own code) that learns through it.

The reference trajectories below are built without the adapter: gymnax's step splits its key into a step key and a
reset key, so the adapter's transition is ``jaxmdp.step(step_key, ...)`` and, when the episode is done, its state is
``jaxmdp.reset(reset_key, ...)``'s.
"""

from __future__ import annotations

import functools
import importlib.util
import subprocess
import sys
import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmdp
from jaxmdp.gymnax_env import NEVER, GymnaxParams, GymnaxState

from conftest import REPO, random_mdp
from stat_checks import key as seeded_key

gymnax = pytest.importorskip("gymnax")
from gymnax.environments import environment, spaces  # noqa: E402
from gymnax.wrappers.purerl import FlattenObservationWrapper, LogWrapper  # noqa: E402

N_STEPS = 40


def _point_mass_mdp(rng: np.random.Generator, S: int, A: int, H: int | None) -> jaxmdp.MDP:
    """A random MDP with several start states, a stochastic kernel and point-mass rewards (no Beta sampler to
    compile, which dominates the compile time of a step)."""
    T = rng.random((S, A, S)) * (rng.random((S, A, S)) < 0.5) + 0.05
    P0 = rng.random(S) * (rng.random(S) < 0.7) + np.eye(S)[0]
    return jaxmdp.custom_mdp(T / T.sum(-1, keepdims=True), P0=P0 / P0.sum(), H=H,
                             reward_mean=rng.uniform(0, 1, (S, A, S)), reward_conc=np.zeros((S, A, S)))


def _mdps() -> dict[str, jaxmdp.MDP | jaxmdp.BlockMDP]:
    rng = np.random.default_rng(5)
    episodic = _point_mass_mdp(rng, S=5, A=3, H=4)
    return {
        "beta": random_mdp(rng, S=5, A=3, H=4),  # Beta and point-mass rewards
        "episodic": episodic,
        "continuous": _point_mass_mdp(rng, S=5, A=3, H=None),
        "block": jaxmdp.block_mdp(episodic, "one_hot", "gaussian", scale=0.3),
        "block_image": jaxmdp.block_mdp(jaxmdp.make("DeepSea", episodic=True, seed=0, size=4), "image"),
    }


MDPS = _mdps()


def _reached_obs(mdp, info, observation):
    """What the adapter's final_observation must be: the reached state's encoding (a BlockMDP: jaxmdp's)."""
    if isinstance(mdp, jaxmdp.BlockMDP):
        return info["final_observation"]
    s = info["final_observation"]
    return s if observation == "index" else jax.nn.one_hot(s, mdp.n_states, dtype=jnp.float32)


def _encode(mdp, obs, observation):
    if isinstance(mdp, jaxmdp.BlockMDP) or observation == "index":
        return obs
    return jax.nn.one_hot(obs, mdp.n_states, dtype=jnp.float32)


def _reference_rollout(key, mdp, actions, observation, max_steps):
    """The adapter's trajectory computed from jaxmdp.reset/step and gymnax's key split and time limit."""
    k_reset, k_run = jax.random.split(key)
    obs, state = jaxmdp.reset(k_reset, mdp)
    obs = _encode(mdp, obs, observation)

    def body(carry, x):
        obs, state, time = carry
        k, a = x
        k_step, k_reset = jax.random.split(k)
        o, stepped, r, term, _, info = jaxmdp.step(k_step, state, a, mdp)
        time = time + 1
        trunc = time >= max_steps
        done = term | trunc
        o_reset, s_reset = jaxmdp.reset(k_reset, mdp)
        # Truncated but not terminated: jaxmdp.step did not reset, its state is the one reached.
        new_state = jax.tree.map(lambda x, y: jnp.where(done, x, y), s_reset, stepped)
        new_obs = jnp.where(done, _encode(mdp, o_reset, observation), _encode(mdp, o, observation))
        out = (obs, r, term, trunc, _reached_obs(mdp, info, observation), new_state.state, new_state.h)
        return (new_obs, new_state, jnp.where(done, 0, time)), out

    keys = jax.random.split(k_run, actions.shape[0])
    return jax.lax.scan(body, (obs, state, jnp.zeros((), jnp.int32)), (keys, actions))[1]


def _adapter_rollout(key, env, params, actions):
    k_reset, k_run = jax.random.split(key)
    obs, state = env.reset(k_reset, params)

    def body(carry, x):
        obs, state = carry
        k, a = x
        o, state2, r, term, trunc, info = env.step(k, state, a, params)
        out = (obs, r, term, trunc, info["final_observation"], state2.mdp_state.state, state2.mdp_state.h, state2.time,
               info["discount"], info)
        return (o, state2), out

    keys = jax.random.split(k_run, actions.shape[0])
    return jax.lax.scan(body, (obs, state), (keys, actions))[1]


def _actions(seed, mdp, n=N_STEPS):
    return jnp.asarray(np.random.default_rng(seed).integers(0, mdp.n_actions, n), jnp.int32)


@functools.partial(jax.jit, static_argnums=(0, 5, 6))
def _both_rollouts(env, params, mdp, key, actions, observation, max_steps):
    """The adapter's rollout, the reference's, and whether the observation space holds each (final) observation:
    one program."""
    got = _adapter_rollout(key, env, params, actions)
    ref = _reference_rollout(key, mdp, actions, observation, max_steps)
    contains = jax.vmap(env.observation_space(params).contains)
    return got, ref, (contains(got[0]), contains(got[4]))


@pytest.mark.parametrize("name,observation,max_steps", [
    ("beta", "one_hot", None), ("episodic", "index", 3), ("continuous", "one_hot", None),
    ("continuous", "index", 3), ("block", None, None), ("block_image", None, 3),
])
def test_transitions_and_rewards_are_jaxmdp_steps(name, observation, max_steps):
    mdp = MDPS[name]
    env, params = jaxmdp.as_gymnax(mdp, observation, max_steps)
    got, ref, contained = _both_rollouts(env, params, mdp, jax.random.key(11), _actions(1, mdp), observation,
                                         NEVER if max_steps is None else max_steps)
    names = ("observation", "reward", "terminated", "truncated", "final_observation", "state", "h")
    for what, g, r in zip(names, got, ref):
        np.testing.assert_array_equal(np.asarray(g), np.asarray(r), err_msg=what)
    obs, reward, term, trunc, final, states, h, time, discount, _ = got
    np.testing.assert_array_equal(discount, 1.0 - np.asarray(term, np.float32))
    # Episodes: an episodic MDP terminates exactly at every H-th step since the last reset, a continuous one never;
    # a time limit truncates exactly at every max_steps-th step; gymnax's counter restarts at each end.
    H, limit = mdp.H, NEVER if max_steps is None else max_steps
    since_reset, expected_term, expected_trunc = 0, [], []
    for _ in range(N_STEPS):
        since_reset += 1
        expected_term.append(H is not None and since_reset == H)
        expected_trunc.append(since_reset == limit)
        if expected_term[-1] or expected_trunc[-1]:
            since_reset = 0
    np.testing.assert_array_equal(term, expected_term)
    np.testing.assert_array_equal(trunc, expected_trunc)
    done = np.asarray(term) | np.asarray(trunc)
    assert done.any() == (H is not None or max_steps is not None)
    np.testing.assert_array_equal(np.asarray(time)[done], 0)  # auto-reset: a fresh episode's state
    np.testing.assert_array_equal(np.asarray(h)[done], 0)
    assert np.all(np.isfinite(np.asarray(reward)))
    # The observation space holds every observation and final observation (all zeros past a BlockMDP's end).
    obs_space = env.observation_space(params)
    for o, inside in zip((obs, final), contained):
        assert o.shape[1:] == tuple(obs_space.shape) and o.dtype == obs_space.dtype
        assert np.all(inside)
    if observation == "one_hot":
        np.testing.assert_array_equal(np.asarray(obs).sum(-1), 1.0)


def test_auto_reset_starts_a_fresh_episode_from_the_reset_key():
    mdp = MDPS["episodic"]
    env, params = jaxmdp.as_gymnax(mdp)
    key = jax.random.key(12)
    _, state = env.reset(jax.random.fold_in(key, 0), params)
    actions = _actions(2, mdp, mdp.H)
    for t in range(mdp.H):
        k = jax.random.fold_in(key, t + 1)
        obs, state_next, reward, term, trunc, info = env.step(k, state, actions[t], params)
        assert bool(term) == (t == mdp.H - 1) and not bool(trunc)
        if not term:
            assert int(state_next.time) == t + 1 and int(state_next.mdp_state.h) == t + 1
            state = state_next
    k_step, k_reset = jax.random.split(k)
    s0 = jax.jit(jaxmdp.reset)(k_reset, mdp)[1].state
    assert int(state_next.mdp_state.state) == int(s0) and int(state_next.time) == 0 and int(state_next.mdp_state.h) == 0
    np.testing.assert_array_equal(obs, jax.nn.one_hot(s0, mdp.n_states))
    # The episode's last observation: the state the H-th action reached, as jaxmdp.step reports it.
    reached = jax.jit(jaxmdp.step)(k_step, state.mdp_state, actions[-1], mdp)[5]["final_observation"]
    np.testing.assert_array_equal(info["final_observation"], jax.nn.one_hot(reached, mdp.n_states))
    assert float(info["discount"]) == 0.0
    # The state before gymnax's reset (step_env's) ends the episode: is_terminal holds there, not one step before.
    stepped = jax.jit(env.step_env)(k_step, state, actions[-1], params)[1]
    terminal = jax.jit(env.is_terminal)
    assert bool(terminal(stepped, params)) and int(stepped.mdp_state.h) == mdp.H
    assert not bool(terminal(state, params))


@pytest.mark.parametrize("name,observation", [
    ("episodic", "one_hot"), ("episodic", "index"), ("continuous", "one_hot"), ("block", None), ("block_image", None),
])
def test_spaces_and_names(name, observation):
    mdp = MDPS[name]
    env, params = jaxmdp.as_gymnax(mdp, observation)
    assert isinstance(env, environment.Environment)
    action_space, obs_space = env.action_space(params), env.observation_space(params)
    assert isinstance(action_space, spaces.Discrete) and action_space.n == mdp.n_actions == env.num_actions
    assert bool(action_space.contains(action_space.sample(jax.random.key(13))))
    inner = mdp.mdp if isinstance(mdp, jaxmdp.BlockMDP) else mdp
    if observation == "index":
        assert isinstance(obs_space, spaces.Discrete) and obs_space.n == mdp.n_states
    elif observation == "one_hot":
        assert isinstance(obs_space, spaces.Box) and obs_space.shape == (mdp.n_states,)
        assert (obs_space.low, obs_space.high, obs_space.dtype) == (0.0, 1.0, jnp.float32)
    elif name == "block_image":  # noiseless: bounded by the table's values and 0
        assert isinstance(obs_space, spaces.Box) and obs_space.shape == mdp.obs_shape
        assert obs_space.low == 0.0 and obs_space.high == float(np.max(mdp.emissions)) > 0
        assert not bool(obs_space.contains(jnp.full(obs_space.shape, obs_space.high + 1)))
    else:  # Gaussian noise: unbounded
        assert obs_space.low == -np.inf and obs_space.high == np.inf
    assert env.name == f"jaxmdp-{inner.info.family}" + (f"-{mdp.emission_kind}" if name.startswith("block") else "")
    assert isinstance(params, GymnaxParams) and int(params.max_steps_in_episode) == NEVER
    _, state = env.reset(jax.random.key(0), params)
    assert isinstance(state, GymnaxState) and int(state.time) == 0


def test_jit_and_vmap_over_environments_and_over_mdps():
    # vmap over environments of one MDP: each equals its own unbatched step.
    mdp = MDPS["block"]
    env, params = jaxmdp.as_gymnax(mdp)
    n = 5
    keys = jax.random.split(jax.random.key(14), n)
    obs, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)
    actions = jnp.arange(n) % mdp.n_actions
    step_keys = jax.random.split(jax.random.fold_in(jax.random.key(14), 1), n)
    batched = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))(step_keys, states, actions, params)
    for i in range(n):
        o, s = env.reset(keys[i], params)
        single = env.step(step_keys[i], s, actions[i], params)
        for b, u in zip(jax.tree.leaves(batched), jax.tree.leaves(single)):
            np.testing.assert_array_equal(np.asarray(b)[i], np.asarray(u))
    # vmap over a stack of MDPs of one shape through the params pytree: member i equals the environment of MDP i.
    members = [jaxmdp.make("DeepSea", episodic=True, seed=s, size=5) for s in range(3)]
    env, _ = jaxmdp.as_gymnax(members[0])
    stacked = GymnaxParams(mdp=jaxmdp.stack(members).strip(), max_steps_in_episode=jnp.int32(NEVER))
    in_axes = GymnaxParams(mdp=0, max_steps_in_episode=None)
    keys = jax.random.split(jax.random.key(15), len(members))
    actions = jnp.stack([_actions(16 + i, members[0]) for i in range(len(members))])
    rollout = jax.jit(lambda k, a, p: _adapter_rollout(k, env, p, a))
    got = jax.jit(jax.vmap(rollout, in_axes=(0, 0, in_axes)))(keys, actions, stacked)
    for i, m in enumerate(members):
        # The environment object holds only static facts, so one of member 0 with member i's params is member i's.
        env_i, params_i = jaxmdp.as_gymnax(m)
        assert env_i.observation_space(params_i).shape == env.observation_space(params_i).shape
        ref = rollout(keys[i], actions[i], params_i)
        for what, g, r in zip(("observation", "reward", "terminated"), got, ref):
            np.testing.assert_array_equal(np.asarray(g)[i], np.asarray(r), err_msg=f"member {i}: {what}")
    # The members differ (their action maps do), so the check above is not vacuous.
    assert not np.array_equal(np.asarray(got[0])[0], np.asarray(got[0])[1])


@pytest.mark.parametrize("name", ["episodic", "block_image"])
def test_gymnax_wrappers(name):
    mdp = MDPS[name]
    env, params = jaxmdp.as_gymnax(mdp)
    wrapped = LogWrapper(FlattenObservationWrapper(env))
    obs_space = wrapped.observation_space(params)
    dim = int(np.prod(env.observation_space(params).shape))
    assert obs_space.shape == (dim,)
    n_envs, n_steps = 4, 3 * mdp.H
    key = jax.random.key(17)
    actions = jax.random.randint(key, (n_steps, n_envs), 0, mdp.n_actions)

    @jax.jit
    def run(key):
        _, states = jax.vmap(wrapped.reset, in_axes=(0, None))(jax.random.split(key, n_envs), params)

        def body(states, x):
            k, a = x
            obs, states, reward, term, trunc, info = jax.vmap(wrapped.step, in_axes=(0, 0, 0, None))(
                jax.random.split(k, n_envs), states, a, params)
            return states, (obs, reward, term, info)

        return jax.lax.scan(body, states, (jax.random.split(key, n_steps), actions))[1]

    obs, reward, term, info = run(key)
    assert obs.shape == (n_steps, n_envs, dim) and info["final_observation"].shape == (n_steps, n_envs, dim)
    # LogWrapper's episode returns and lengths: the rewards of each H-step episode, summed here independently.
    episode_returns = np.asarray(reward).reshape(3, mdp.H, n_envs).sum(1)
    ends = np.asarray(info["returned_episode"])
    np.testing.assert_array_equal(ends, np.asarray(term))
    np.testing.assert_array_equal(np.nonzero(ends[:, 0])[0], [mdp.H - 1, 2 * mdp.H - 1, 3 * mdp.H - 1])
    np.testing.assert_allclose(np.asarray(info["returned_episode_returns"])[ends].reshape(3, n_envs),
                               episode_returns, rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(info["returned_episode_lengths"])[ends], mdp.H)


def test_input_errors():
    mdp = MDPS["episodic"]
    with pytest.raises(TypeError, match="mdp must be a jaxmdp.MDP or jaxmdp.BlockMDP"):
        jaxmdp.as_gymnax("RiverSwim")
    with pytest.raises(ValueError, match="stacked batch"):
        jaxmdp.as_gymnax(jaxmdp.stack([mdp, mdp]))
    with pytest.raises(ValueError, match=r"observation must be one of \['one_hot', 'index'\].*did you mean 'one_hot'"):
        jaxmdp.as_gymnax(mdp, "onehot")
    with pytest.raises(ValueError, match=r"observation must be one of \['emission'\] for a BlockMDP"):
        jaxmdp.as_gymnax(MDPS["block"], "index")
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match="max_steps_in_episode must be an integer"):
            jaxmdp.as_gymnax(mdp, max_steps_in_episode=bad)


def test_missing_gymnax_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "gymnax.environments.environment", None)
    with pytest.raises(ImportError, match=r'pip install "[\w.-]+\[gymnax\]"'):
        jaxmdp.as_gymnax(MDPS["episodic"])


def test_jaxmdp_imports_without_gymnax():
    code = (
        "import sys\n"
        "sys.modules['gymnax'] = None\n"  # import gymnax raises ImportError
        "import jaxmdp, jaxmdp.gymnax_env\n"
        "assert callable(jaxmdp.as_gymnax)\n"
        "try:\n"
        "    jaxmdp.as_gymnax(jaxmdp.make('RiverSwim', episodic=True, seed=0, size=3))\n"
        "except ImportError as err:\n"
        "    print(err)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "[gymnax]" in out.stdout and "pip install" in out.stdout


# --- PPO through the adapter, with the notebook's own code ------------------------------------------------------------

NOTEBOOK = REPO / "notebooks" / "src" / "05_gymnax_and_ppo.py"
PPO_SEEDS = 6
PPO_MIN_SUCCESSES = 3
PPO_THRESHOLD = 0.5


def _notebook_definitions(monkeypatch: pytest.MonkeyPatch) -> dict:
    """The namespace of the notebook's code cells run in order up to the one that defines ``make_train``, as a
    module registered for the test's duration (flax's dataclass modules look their module up in ``sys.modules``)."""
    spec = importlib.util.spec_from_file_location("notebook_builder", REPO / "notebooks" / "build.py")
    builder = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(builder)
    module = types.ModuleType("notebook_05_gymnax_and_ppo")
    monkeypatch.setitem(sys.modules, module.__name__, module)
    for kind, source in builder.parse_cells(NOTEBOOK.read_text()):
        if kind == "code":
            exec(compile(source, str(NOTEBOOK), "exec"), module.__dict__)
            if "make_train" in module.__dict__:
                return module.__dict__
    raise AssertionError(f"{NOTEBOOK.relative_to(REPO)} defines no make_train")


@pytest.mark.nightly  # by default: test_transitions_and_rewards_are_jaxmdp_steps (every step exactly jaxmdp's)
@pytest.mark.statistical(p=1.5e-7)
def test_ppo_learns_through_the_adapter(monkeypatch):
    # Each seed's learned policy is evaluated exactly (finite-horizon policy evaluation on the MDP): it succeeds when
    # its expected return is >= PPO_THRESHOLD = 0.5, far above the random policy's 0.13 and below the optimal 1.
    # Seeds have independent keys, so the number of failures is Binomial(PPO_SEEDS, q), q a seed's failure
    # probability. Measured with the notebook's CONFIG on 1 024 independent seeds: no failure (the lowest return
    # was 0.85). 0 failures in 1 024 seeds has probability <= 0.99^1024 < 4e-5 if q >= 0.01, so q < 0.01; the
    # test fails when more than PPO_SEEDS - PPO_MIN_SUCCESSES = 3 of 6 seeds fail, with probability
    # P(Binomial(6, q) >= 4) <= C(6, 4) q^4 <= 15 * 1e-8 = 1.5e-7.
    ns = _notebook_definitions(monkeypatch)
    mdp, reference = ns["mdp"], ns["reference"]
    assert float(reference.random) + 0.3 < PPO_THRESHOLD < float(reference.optimal) - 0.3
    network, train = ns["make_train"](ns["CONFIG"], ns["env"], ns["env_params"])
    policy_return = jax.jit(jax.vmap(lambda p: ns["policy_return"](network, p, mdp)))
    # The exact evaluation, checked independently: the untrained policy is uniform (its logits' layer starts at
    # zero), and the uniform policy's exact return is jaxmdp's random value.
    untrained = jax.vmap(network.init, in_axes=(0, None))(jax.random.split(jax.random.key(0), 2),
                                                          jnp.zeros(mdp.n_states))
    np.testing.assert_allclose(policy_return(untrained), float(reference.random), rtol=1e-5)
    # Seeds one after another in one program (lax.map): XLA compiles the single-seed train much faster than the
    # vmapped one on a CPU; each seed's computation is the same either way.
    params, mean_returns = jax.jit(lambda keys: jax.lax.map(train, keys))(
        jax.random.split(seeded_key(54), PPO_SEEDS))
    values = np.asarray(policy_return(params))
    assert np.all(np.isfinite(np.asarray(mean_returns)))
    assert int(np.sum(values >= PPO_THRESHOLD)) >= PPO_MIN_SUCCESSES, values
