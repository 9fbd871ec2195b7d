"""Source of notebooks/05_gymnax_and_ppo.ipynb (build: PYTHONPATH=$PWD python scripts/build_notebooks.py).

tests/test_gymnax_env.py runs this notebook's code cells up to the one that defines ``make_train`` and trains with
that very code, so the PPO below lives here only.
"""

# %% [markdown]
# # A gymnax environment and PPO
#
# `env, env_params = jaxmdp.as_gymnax(mdp)` turns any jaxmdp MDP or BlockMDP into a gymnax `Environment`: gymnax's
# spaces, `default_params`, `reset`/`step` with auto-reset, and so gymnax's wrappers and training loops written for
# gymnax work on it unchanged. This notebook:
#
# 1. makes the environment of a small episodic DeepSea and looks at its spaces and one episode;
# 2. plays it at random through gymnax's `FlattenObservationWrapper` and `LogWrapper`, and checks the logged mean
#    return against the random policy's exact value;
# 3. trains a short PPO written in the style of PureJaxRL (one jitted `train` function: `lax.scan` over updates,
#    vectorised environments, GAE, the clipped objective) on 8 seeds at once, and evaluates every learned policy
#    *exactly* by dynamic programming on the MDP.
#
# It needs gymnax (`pip install "jaxmdp[gymnax]"`); it runs on a laptop CPU in well under a minute, mostly
# compilation.

# %%
import jaxmdp  # first: it sets an XLA flag before JAX makes its backend

from typing import Any, NamedTuple

import distrax
import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax.training.train_state import TrainState
from gymnax.wrappers.purerl import FlattenObservationWrapper, LogWrapper
from matplotlib.figure import Figure

from jaxmdp import dynamic_programming as dp

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. The environment
#
# DeepSea (size 5, episodic, `H = 5`): the agent descends one row per step and must move "right" at every step to
# reach the treasure (return 1); every "left" earns a small reward, so a random agent finds the treasure in one
# episode of 32 and mostly collects the small rewards, and a greedy one learns to go left. Which action means
# "right" is drawn per state (`randomize_actions`), so no fixed action sequence works.
#
# The observation of a plain MDP is the one-hot vector of its state (`observation="index"` gives the integer
# instead; a BlockMDP gives its emission). An episodic MDP terminates after `H` steps; a continuous one never does,
# unless `max_steps_in_episode` truncates it.

# %%
mdp = jaxmdp.make("DeepSea", episodic=True, seed=0, size=5)
env, env_params = jaxmdp.as_gymnax(mdp)
reference = jaxmdp.reference_values(mdp)
print(env.name, "| actions:", env.action_space(env_params), "| observations:", env.observation_space(env_params))
print(f"optimal return {float(reference.optimal):.3f}, random policy's return {float(reference.random):.3f}")

obs, state = env.reset(jax.random.key(0), env_params)
for t, k in enumerate(jax.random.split(jax.random.key(1), mdp.H)):
    k_act, k_step = jax.random.split(k)
    action = env.action_space(env_params).sample(k_act)
    obs, state, reward, terminated, truncated, info = env.step(k_step, state, action, env_params)
    print(f"t={t} action {int(action)} -> state {int(jnp.argmax(info['final_observation']))}, "
          f"reward {float(reward):.3f}, terminated {bool(terminated)}")
assert bool(terminated) and int(state.time) == 0  # the H-th step ends the episode; gymnax reset the state

# %% [markdown]
# ## 2. gymnax's wrappers and random play
#
# PureJaxRL wraps its environments in `FlattenObservationWrapper` (observations as vectors) and `LogWrapper`
# (episode returns in `info`). 4 096 random episodes through both: the logged mean return is the random policy's
# exact value up to sampling error.

# %%
wrapped = LogWrapper(FlattenObservationWrapper(env))


@jax.jit
def random_returns(key: jax.Array, n_envs: int = 4096) -> jax.Array:
    """The return of one random episode in each of ``n_envs`` environments, from ``LogWrapper``'s info."""
    k_reset, k_run = jax.random.split(key)
    _, states = jax.vmap(wrapped.reset, in_axes=(0, None))(jax.random.split(k_reset, n_envs), env_params)

    def one_step(states, k):
        k_act, k_step = jax.random.split(k)
        actions = jax.random.randint(k_act, (n_envs,), 0, env.num_actions)
        _, states, _, _, _, info = jax.vmap(wrapped.step, in_axes=(0, 0, 0, None))(
            jax.random.split(k_step, n_envs), states, actions, env_params)
        return states, info

    _, info = jax.lax.scan(one_step, states, jax.random.split(k_run, mdp.H))
    assert info["returned_episode"].shape == (mdp.H, n_envs)
    return info["returned_episode_returns"][-1]  # the H-th step completes every episode


returns = random_returns(jax.random.key(2))
print(f"random play: mean return {float(returns.mean()):.4f} over {returns.size} episodes "
      f"(exact {float(reference.random):.4f}); treasure found in {float(jnp.mean(returns > 0.5)):.1%}")
# 4 096 episodes of returns in [0, 1.2]: the standard error is below 0.02, so 0.1 is far outside sampling error.
assert abs(float(returns.mean()) - float(reference.random)) < 0.1

# %% [markdown]
# ## 3. PPO in the style of PureJaxRL
#
# An actor-critic MLP (separate policy and value networks), then `make_train(config, env, env_params)` returning
# the network and one pure function `train(key)`: it collects `num_steps` transitions from `num_envs` environments
# (`lax.scan` over steps, `vmap` over environments), computes generalised advantage estimates (a reverse
# `lax.scan`), and runs `update_epochs` epochs of minibatch updates of the clipped surrogate objective plus a
# clipped value loss and an entropy bonus; a `lax.scan` over updates repeats this. Everything is one jitted
# program, so `jax.vmap(train)` trains many seeds at once. Per update, only the mean return of the episodes
# completed is kept (not every step's info).
#
# Two choices differ from PureJaxRL's defaults. The advantages are not normalised per minibatch: the rewards lie in
# [0, 1], and once a policy is deterministic on a deterministic MDP the advantages are all near zero, so dividing
# by their spread would turn rounding noise into large updates. The entropy bonus is larger (0.05) and the
# learning rate smaller (1e-3) than usual, because the small rewards of "left" otherwise make PPO greedy before
# it has found the treasure.
#
# `policy_return` evaluates a learned policy exactly: the network's action probabilities at every state's
# observation form a stationary policy `pi[S, A]`, whose expected return from `P0` is a finite-horizon policy
# evaluation on the MDP (`jaxmdp.dynamic_programming`); no sampling noise.

# %%
CONFIG = {
    "num_envs": 32,
    "num_steps": 10,  # two episodes of DeepSea-5 per environment and update
    "total_timesteps": 12_800,  # 40 updates of 320 transitions
    "update_epochs": 4,
    "num_minibatches": 4,
    "lr": 1e-3,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "clip_eps": 0.2,
    "ent_coef": 0.05,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
    "hidden": 64,
}


class ActorCritic(nn.Module):
    """Two tanh layers for the policy's logits, two for the value. The logits' layer starts at zero, so the
    untrained policy is uniform."""

    num_actions: int
    hidden: int = 64

    @nn.compact
    def __call__(self, x: jax.Array) -> tuple[distrax.Categorical, jax.Array]:
        pi = nn.tanh(nn.Dense(self.hidden)(x))
        pi = nn.tanh(nn.Dense(self.hidden)(pi))
        logits = nn.Dense(self.num_actions, kernel_init=nn.initializers.zeros)(pi)
        v = nn.tanh(nn.Dense(self.hidden)(x))
        v = nn.tanh(nn.Dense(self.hidden)(v))
        return distrax.Categorical(logits=logits), jnp.squeeze(nn.Dense(1)(v), -1)


class Transition(NamedTuple):
    obs: jax.Array
    action: jax.Array
    reward: jax.Array
    done: jax.Array
    value: jax.Array
    log_prob: jax.Array


def policy_return(network: ActorCritic, params: Any, mdp: jaxmdp.MDP) -> jax.Array:
    """Exact expected return from ``P0`` of the network's stochastic policy on a plain MDP (one-hot observations)."""
    probs = network.apply(params, jnp.eye(mdp.n_states, dtype=jnp.float32))[0].probs
    _, V = dp.finite_horizon_policy_evaluation(mdp, probs.astype(mdp.dtype))
    return mdp.P0 @ V[0]


def make_train(config: dict, env: Any, env_params: Any):
    """``train(key) -> (network params, mean episode return per update)``: PPO on ``env``."""
    num_envs, num_steps = config["num_envs"], config["num_steps"]
    num_updates = config["total_timesteps"] // (num_envs * num_steps)
    minibatch_size = num_envs * num_steps // config["num_minibatches"]
    env = LogWrapper(FlattenObservationWrapper(env))
    network = ActorCritic(env.action_space(env_params).n, config["hidden"])
    reset = jax.vmap(env.reset, in_axes=(0, None))
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    def loss_fn(params, batch: Transition, advantages, targets):
        dist, value = network.apply(params, batch.obs)
        log_prob = dist.log_prob(batch.action)
        ratio = jnp.exp(log_prob - batch.log_prob)
        clipped = jnp.clip(ratio, 1 - config["clip_eps"], 1 + config["clip_eps"])
        actor = -jnp.minimum(ratio * advantages, clipped * advantages)
        value_clipped = batch.value + jnp.clip(value - batch.value, -config["clip_eps"], config["clip_eps"])
        critic = 0.5 * jnp.maximum((value - targets) ** 2, (value_clipped - targets) ** 2)
        return actor.mean() + config["vf_coef"] * critic.mean() - config["ent_coef"] * dist.entropy().mean()

    def gae(traj: Transition, last_value: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Generalised advantage estimates and value targets, by a reverse scan over the steps."""

        def backward(carry, t: Transition):
            advantage, next_value = carry
            not_done = 1.0 - t.done
            delta = t.reward + config["gamma"] * next_value * not_done - t.value
            advantage = delta + config["gamma"] * config["gae_lambda"] * not_done * advantage
            return (advantage, t.value), advantage

        _, advantages = jax.lax.scan(backward, (jnp.zeros_like(last_value), last_value), traj, reverse=True)
        return advantages, advantages + traj.value

    def train(key: jax.Array):
        k_init, k_reset, k_run = jax.random.split(key, 3)
        obs_shape = env.observation_space(env_params).shape
        tx = optax.chain(optax.clip_by_global_norm(config["max_grad_norm"]), optax.adam(config["lr"], eps=1e-5))
        state = TrainState.create(apply_fn=network.apply, params=network.init(k_init, jnp.zeros(obs_shape)), tx=tx)
        obs, env_state = reset(jax.random.split(k_reset, num_envs), env_params)

        def update(runner, key):
            state, env_state, obs = runner
            k_steps, k_epochs = jax.random.split(key)

            def env_step(carry, key):
                env_state, obs = carry
                k_act, k_env = jax.random.split(key)
                dist, value = network.apply(state.params, obs)
                action = dist.sample(seed=k_act)
                next_obs, env_state, reward, terminated, truncated, info = step(
                    jax.random.split(k_env, num_envs), env_state, action, env_params)
                done = jnp.logical_or(terminated, truncated).astype(jnp.float32)
                transition = Transition(obs, action, reward, done, value, dist.log_prob(action))
                return (env_state, next_obs), (transition, info["returned_episode"], info["returned_episode_returns"])

            (env_state, obs), (traj, finished, returns) = jax.lax.scan(
                env_step, (env_state, obs), jax.random.split(k_steps, num_steps))
            advantages, targets = gae(traj, network.apply(state.params, obs)[1])

            def epoch(state, key):
                flat = jax.tree.map(lambda x: x.reshape(num_steps * num_envs, *x.shape[2:]),
                                    (traj, advantages, targets))
                order = jax.random.permutation(key, num_steps * num_envs)
                minibatches = jax.tree.map(
                    lambda x: x[order].reshape(config["num_minibatches"], minibatch_size, *x.shape[1:]), flat)

                def minibatch(state, mb):
                    grads = jax.grad(loss_fn)(state.params, *mb)
                    return state.apply_gradients(grads=grads), None

                return jax.lax.scan(minibatch, state, minibatches)[0], None

            state, _ = jax.lax.scan(epoch, state, jax.random.split(k_epochs, config["update_epochs"]))
            mean_return = jnp.sum(returns * finished) / jnp.maximum(jnp.sum(finished), 1)
            return (state, env_state, obs), mean_return

        (state, _, _), mean_returns = jax.lax.scan(
            update, (state, env_state, obs), jax.random.split(k_run, num_updates))
        return state.params, mean_returns

    return network, train


# %% [markdown]
# ## 4. Training 8 seeds at once
#
# `jax.jit(jax.vmap(train))` over 8 independent keys: one compiled program trains all seeds in lockstep. Each
# learned policy is then evaluated exactly.

# %%
network, train = make_train(CONFIG, env, env_params)
seed_keys = jax.random.split(jax.random.key(42), 8)
params, mean_returns = jax.jit(jax.vmap(train))(seed_keys)
learned = jax.vmap(policy_return, in_axes=(None, 0, None))(network, params, mdp)
print("exact return of each seed's learned policy:", np.asarray(learned))
print(f"optimal {float(reference.optimal):.3f}, random {float(reference.random):.3f}")

fig = Figure(figsize=(7, 3.5))
ax = fig.subplots()
steps = np.arange(1, mean_returns.shape[1] + 1) * CONFIG["num_envs"] * CONFIG["num_steps"]
ax.plot(steps, np.asarray(mean_returns).T, color="tab:blue", alpha=0.4, lw=1)
ax.plot(steps, np.asarray(mean_returns).mean(0), color="tab:blue", lw=2, label="PPO, mean of 8 seeds")
ax.axhline(float(reference.optimal), color="k", ls="--", lw=1, label="optimal")
ax.axhline(float(reference.random), color="tab:red", ls=":", lw=1, label="random policy")
ax.set_xlabel("environment steps (per seed)")
ax.set_ylabel("mean return of the episodes ended")
ax.set_title("PPO on DeepSea-5 through jaxmdp.as_gymnax")
ax.legend(loc="lower right")
fig
