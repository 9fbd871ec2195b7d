"""Source of notebooks/03_blockmdps_and_deep_agents.ipynb (build: PYTHONPATH=$PWD python scripts/build_notebooks.py)."""

# %% [markdown]
# # BlockMDPs and deep agents
#
# A BlockMDP (paper §3.1, App. A.2) is a tabular MDP whose agent never sees the state: it sees an *observation*, a
# row of an emission table plus optional noise. The states, rewards and dynamics stay the MDP's, so its hardness
# measures and the exact regret of any policy are still known, while a deep agent has to learn from the
# observations. This notebook covers:
#
# 1. emission tables: `state_info` and `one_hot` for a RiverSwim and an episodic DeepSea, and the `image` emission
#    of a MiniGridEmpty state;
# 2. a noisy rollout: the same trajectory observed without noise, with Gaussian and with Student-t noise;
# 3. a deep agent's regret curve (DQN on a small RiverSwim through `state_info`) beside a tabular agent's
#    (Q-learning on the same MDP) and the random agent's, all with `jaxmdp.experiment.runner`.
#
# Everything runs on a laptop CPU in about a minute, mostly compilation.

# %%
import jax
import jax.numpy as jnp
import numpy as np
from matplotlib.figure import Figure

import agents  # importing jaxmdp (agents does) before any JAX computation lets it set an XLA flag it needs
import jaxmdp
from jaxmdp.blockmdp import family_symbols
from jaxmdp.experiment import runner

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. Emission tables
#
# `jaxmdp.emission_table(mdp, kind)` returns the observation of every state at once: `[S, *obs_shape]` for a
# continuous MDP, `[H, S, *obs_shape]` for an episodic one (row `[h, s]`: state `s` at in-episode step `h`). The kinds
# are `jaxmdp.EMISSION_KINDS`. `state_info` is the family's node fields (RiverSwim: the position `X`; DeepSea: `(X, Y)`;
# episodic MDPs put `h` in front), the reference's non-tabular benchmark choice; `one_hot` is the state's indicator
# and carries no time.

# %%
print(jaxmdp.EMISSION_KINDS)
river = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, randomize_actions=False)
print("RiverSwim-5, state_info [S, 1]:\n", np.asarray(jaxmdp.emission_table(river, "state_info")).T)
print("RiverSwim-5, one_hot [S, S]:\n", np.asarray(jaxmdp.emission_table(river, "one_hot")))

sea = jaxmdp.make("DeepSea", episodic=True, seed=0, size=4)
sea_info = np.asarray(jaxmdp.emission_table(sea, "state_info"))
sea_hot = np.asarray(jaxmdp.emission_table(sea, "one_hot"))
print("DeepSea-4 (episodic, H =", sea.H, ") state_info", sea_info.shape, "one_hot", sea_hot.shape)
print("state_info at h = 1, rows (h, X, Y) of the states:\n", sea_info[1])
np.testing.assert_array_equal(sea_info[:, :, 0], np.arange(sea.H)[:, None] * np.ones(sea.n_states))  # h in front
np.testing.assert_array_equal(sea_hot[0], sea_hot[-1])                                                 # no time

# %% [markdown]
# The `image` emission is the family's text rendering of the queried state with each symbol replaced by its index
# in the family's symbol list (`tensor` one-hot encodes the same grid). Here a MiniGridEmpty state: the agent (an
# arrow for its direction) and the goal `G`.

# %%
grid_world = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=5)
image = np.asarray(jaxmdp.emission_table(grid_world, "image"))
symbols = family_symbols("MiniGridEmpty")
state = 3
print(f"{grid_world.n_states} states, image table {image.shape}; symbols {dict(enumerate(symbols))}")
print(f"state {state} rendered:\n{jaxmdp.render(grid_world, state)}")
print(f"its image:\n{image[state].astype(int)}")
print("its state_info (X, Y, Dir):", np.asarray(jaxmdp.emission_table(grid_world, "state_info"))[state])
decoded = "\n".join("".join(symbols[int(c)] for c in row) for row in image[state])
assert decoded == jaxmdp.render(grid_world, state)  # the image is the rendering, symbol by symbol

# %% [markdown]
# ## 2. A noisy rollout
#
# `jaxmdp.block_mdp(mdp, emission, noise, **params)` wraps an MDP; `jaxmdp.reset` and `jaxmdp.step` then return
# observations instead of state indices. The noise (`"gaussian"`, `"correlated_gaussian"`, `"student_t"`,
# `"correlated_student_t"`) is drawn from a stream of the step's key that the MDP's own sampling never uses, so with
# the same keys the state trajectory is the same whatever the noise: below, one trajectory of a RiverSwim with
# random actions, observed three ways. Student-t noise (3 degrees of freedom) has heavy tails: rare large jumps.

# %%
river8 = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=8, randomize_actions=False)
blocks = {
    "no noise": jaxmdp.block_mdp(river8, "state_info"),
    "gaussian, scale 0.3": jaxmdp.block_mdp(river8, "state_info", "gaussian", scale=0.3),
    "student_t, scale 0.3, df 3": jaxmdp.block_mdp(river8, "state_info", "student_t", scale=0.3, df=3.0),
}


def rollout(block, key, n_steps=200):
    """Observations and states of ``n_steps`` steps under random actions ("right", action 1, with probability 0.8)."""
    k_reset, k_act, k_env = jax.random.split(key, 3)
    obs, env_state = jaxmdp.reset(k_reset, block)
    actions = jax.random.bernoulli(k_act, 0.8, (n_steps,)).astype(jnp.int32)  # mostly right: the river is crossed

    def body(carry, t):
        obs, env_state = carry
        next_obs, next_state, *_ = jaxmdp.step(jax.random.fold_in(k_env, t), env_state, actions[t], block)
        return (next_obs, next_state), (obs, env_state.state)

    _, (observations, states) = jax.lax.scan(body, (obs, env_state), jnp.arange(n_steps))
    return np.asarray(observations[:, 0]), np.asarray(states)


paths = {name: rollout(block, jax.random.key(7)) for name, block in blocks.items()}
states = paths["no noise"][1]
for name, (obs, s) in paths.items():
    np.testing.assert_array_equal(s, states)  # the same state trajectory every time
    noise = obs - states
    print(f"{name:>28}: noise mean {noise.mean():+.3f}, std {noise.std():.3f}, largest |noise| {abs(noise).max():.2f}")
np.testing.assert_array_equal(paths["no noise"][0], states)  # noiseless state_info of RiverSwim is the position

fig = Figure(figsize=(8, 3.2))
ax = fig.subplots()
for name, (obs, _) in paths.items():
    ax.plot(obs, lw=1, label=name, alpha=0.9 if name == "no noise" else 0.7)
ax.set(xlabel="step", ylabel="observation (position X)", title="RiverSwim-8 through state_info")
ax.legend(fontsize=8, loc="upper left")
fig

# %% [markdown]
# ## 3. A deep agent beside a tabular agent and the random agent
#
# The deep agents (`dqn_*`, `boot_dqn_*`, `actor_critic_*`, `actor_critic_rnn_*`, flax networks trained with optax)
# implement the same agent interface as the tabular ones, with `observation="emission"`: the runner hands them the
# BlockMDP's observations, and their regret is exact, the runner evaluating the greedy policy of the network on every
# row of the emission table. Tabular agents refuse a BlockMDP and deep agents a plain MDP; the random agent runs on
# both. One `runner.run` per agent, four seeds in lockstep each.
#
# The MDP: a continuous RiverSwim of 6 states with lazy (`p_lazy = 0.1`) and random (`p_rand = 0.01`) transitions
# and Beta rewards: swimming right pays off only after a long stretch of small losses, so dithering exploration is
# slow. DQN sees the position through `state_info`; Q-learning sees the state index.

# %%
N_STEPS = 20_000
SEEDS = range(4)
mdp = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=6, p_lazy=0.1, p_rand=0.01,
                  make_reward_stochastic=True, randomize_actions=False)
block = jaxmdp.block_mdp(mdp, "state_info")
runs = {}
for name, env in (("dqn_continuous", block), ("q_learning_continuous", mdp), ("random_continuous", block)):
    agent = agents.get(name)
    runs[name] = runner.run(agent, runner.product([env], [agent.default_hparams], SEEDS), N_STEPS, n_records=100)
    score = runs[name].column("normalized_cumulative_regret")[-1] / N_STEPS
    print(f"{name:>22}: regret per step {score.mean():.3f} ± {score.std(ddof=1):.3f} (seeds {score}), "
          f"{runs[name].agent_steps_per_second:,.0f} agent-steps/s after {runs[name].compile_s:.0f} s compiling")

# The random agent's policy estimate is the uniform policy: its logged regret is the exact uniform baseline.
rnd = runs["random_continuous"]
np.testing.assert_allclose(rnd.column("normalized_cumulative_regret"),
                           rnd.column("random_normalized_cumulative_regret"), rtol=1e-5)
try:
    runner.run(agents.get("q_learning_continuous"), runner.product([block], [agents.get(
        "q_learning_continuous").default_hparams], [0]), 10)
except ValueError as err:
    print("a tabular agent on a BlockMDP:", str(err)[:90], "...")

# %% [markdown]
# The curves: the normalised cumulative regret (0 for an optimal policy, 1 per step for the worst one) against the
# steps, mean over the seeds with the seeds' range as a band.

# %%
fig = Figure(figsize=(7, 3.8))
ax = fig.subplots()
for (name, r), colour in zip(runs.items(), ("tab:blue", "tab:orange", "k")):
    curves = r.column("normalized_cumulative_regret")  # [records, seeds]
    ax.plot(r.steps, curves.mean(axis=1), color=colour, label=name, ls="--" if name.startswith("random") else "-")
    ax.fill_between(r.steps, curves.min(axis=1), curves.max(axis=1), color=colour, alpha=0.15, lw=0)
ax.set(xlabel="step", ylabel="normalised cumulative regret", title="RiverSwim-6 (continuous): deep vs tabular")
ax.legend(fontsize=8)
fig

# %% [markdown]
# DQN's regret stays near zero while Q-learning's is still close to the random agent's. The emission is the reason:
# on RiverSwim "right" is optimal in every state, and through `state_info` every state is one number, the position,
# so one network whose "right" output exceeds its "left" output along the whole river is an optimal policy, learnt
# from a few rewarding transitions and generalised to states the agent has barely visited. The tabular agent has to
# learn each state on its own. The hardness of the MDP is unchanged; what an agent can share between states is not.
# `python scripts/regret_table.py --deep` runs every deep agent this way on small RiverSwim, DeepSea and SimpleGrid
# instances (its committed table: `docs/tables/deep_agents_regret.md`).
