"""Source of notebooks/02_agents_and_regret.ipynb (build: PYTHONPATH=$PWD python scripts/build_notebooks.py)."""

# %% [markdown]
# # Agents, the lockstep runner and exact regret
#
# Agents in `jaxmdp` are bundles of pure functions on pytrees, so many seeds, MDPs and hyperparameter sets run in
# lockstep in one compiled program. This notebook covers:
#
# 1. the agent interface (`init`, `act`, `update`, `needs_plan`/`plan`, `policy`) driven by hand in a `lax.scan`;
# 2. the exact expected regret of a policy;
# 3. a grid of agents × MDPs × seeds with `jaxmdp.experiment.runner` (`runner.product`, `runner.run`, `result.column`);
# 4. a check that the logged regrets are exact;
# 5. an agent against the random agent on a small RiverSwim, with seed bands;
# 6. resuming an interrupted run from its checkpoint;
# 7. a hyperparameter search: candidates from `agents.search_spaces.sample_candidates`, run as one batch.
#
# Sizes are small so that everything runs on a laptop CPU in about a minute; compilation dominates at this size.

# %%
import tempfile
from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import agents  # importing jaxmdp (agents does) before any JAX computation lets it set an XLA flag it needs
import jaxmdp
from agents import search_spaces
from hardness.analysis.plotting import bootstrap_ci
from jaxmdp.experiment import indicators, runner
from jaxmdp.experiment.agent_interface import Transition, spec_of

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. The agent interface
#
# `agents.AGENTS` is the registry. An `Agent` holds `init(key, spec, hparams) -> state`, `act(key, state, obs, h)`,
# `update(state, transition) -> state`, `needs_plan(state)` / `plan(key, state)` (an expensive step at episode or
# epoch boundaries; UCRL2 and PSRL use it, Q-learning does not) and `policy(state)`, the agent's current policy
# estimate, used only to measure regret. Hyperparameters are a pytree with numeric leaves.
#
# The MDP: a continuous RiverSwim with a 30% chance that the chosen action is replaced by a random one, stochastic
# rewards and the family's default per-state action permutation (so "action 0" is not always "left").

# %%
print(list(agents.AGENTS))
q_agent = agents.get("q_learning_continuous")
print(q_agent.default_hparams)

river = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=8, p_rand=0.3, make_reward_stochastic=True)
spec = spec_of(river, n_steps=5_000)          # what the agent may know: S, A, masks, the number of steps
print(river, "| spec:", spec.n_states, "states,", spec.n_actions, "actions, episodic:", spec.episodic)

# %% [markdown]
# The interaction loop, written by hand: `act`, `jaxmdp.step` (gymnax-style, with auto-reset), `update`, then
# `plan` when the agent asks for it. `jax.vmap` over keys runs several seeds. (Under `vmap` a `lax.cond` turns into
# a select that computes both branches every step; `jaxmdp.experiment.runner` avoids that by planning under one
# unbatched `cond`, "some member needs to plan", which is what you want for planning agents.)

# %%
def interact(agent, key, mdp, hparams, n_steps):
    k_init, k_plan, k_reset, k_loop = jax.random.split(key, 4)
    state = agent.plan(k_plan, agent.init(k_init, spec_of(mdp, n_steps), hparams))
    obs, env_state = jaxmdp.reset(k_reset, mdp)

    def body(carry, t):
        state, env_state, obs = carry
        k_act, k_env, k_plan = jax.random.split(jax.random.fold_in(k_loop, t), 3)
        action = agent.act(k_act, state, obs, env_state.h)
        next_obs, next_env, reward, terminated, _, info = jaxmdp.step(k_env, env_state, action, mdp)
        state = agent.update(state, Transition(obs=obs, action=action, reward=reward,
                                               next_obs=info["final_observation"], h=env_state.h,
                                               terminated=terminated))
        state = jax.lax.cond(agent.needs_plan(state), lambda s: agent.plan(k_plan, s), lambda s: s, state)
        return (state, next_env, next_obs), reward

    (state, env_state, _), rewards = jax.lax.scan(body, (state, env_state, obs), jnp.arange(n_steps))
    return state, env_state.state, rewards


run_seeds = jax.jit(jax.vmap(lambda key: interact(q_agent, key, river.strip(), q_agent.default_hparams, 5_000)))
states, last_states, rewards = run_seeds(jax.random.split(jax.random.key(0), 4))
print("average sampled reward per seed:", rewards.mean(axis=1))
print("greedy action of seed 0's policy estimate per state:", np.asarray(q_agent.policy(
    jax.tree.map(lambda x: x[0], states))).argmax(-1))

# %% [markdown]
# ## 2. Exact regret of a policy
#
# Regrets are never estimated from sampled rewards: the indicators evaluate the agent's policy estimate exactly on
# the true MDP (paper App. A.1 and App. E). For a continuous MDP the per-step regret of a policy `π` is
# `ρ* − ρ^π(s)`, with `ρ^π(s)` the exact long-run average reward of `π` from the current state `s`, and the
# normalised regret divides it by `ρ* − ρ⁻` (optimal minus worst gain). Both functions are pure, so one `jit(vmap)`
# evaluates a whole batch of policies.

# %%
consts = jax.jit(indicators.indicator_constants)(river.strip())
print(f"optimal gain {float(consts.optimal):.4f}, worst {float(consts.worst):.4f}, random {float(consts.random):.4f}")
uniform = jnp.full((1, river.n_states, river.n_actions), 1.0 / river.n_actions)
policies = jnp.concatenate([uniform, jax.vmap(q_agent.policy)(states)])          # [5, S, A]
where = jnp.concatenate([jnp.zeros(1, jnp.int32), last_states])                  # the state each one is judged from
evaluate = jax.jit(jax.vmap(indicators.instantaneous, in_axes=(None, None, 0, 0, 0)))
inst = evaluate(river.strip(), consts, policies, where, where)
for i, label in enumerate(["uniform policy"] + [f"Q-learning, seed {i}" for i in range(4)]):
    print(f"{label:20s} regret per step {float(inst.regret[i]):.4f}   "
          f"normalised {float(inst.normalized_regret[i]):.4f}")

# %% [markdown]
# ## 3. A grid of agents × MDPs × seeds
#
# `runner.product(mdps, hparams, seeds)` forms every (MDP, hyperparameter set, seed) member; distinct MDPs are
# padded and stacked once. `runner.run(agent, grid, n_steps)` runs all members in lockstep in one compiled loop and
# logs the exact indicators every `log_period` steps (100, the reference's default). One call per agent: an agent's
# functions are part of the compiled program. Planning agents (`"ucrl2"`, `"psrl_continuous"`) run the same way;
# they are left out here only because each agent costs a few seconds of compilation.

# %%
mdps = [river, jaxmdp.make("RiverSwim", episodic=False, seed=0, size=12, p_rand=0.3, make_reward_stochastic=True)]
seeds = range(6)
N_STEPS = 20_000
results = {}
for name in ("random_continuous", "q_learning_continuous"):
    agent = agents.get(name)
    grid = runner.product(mdps, [agent.default_hparams], seeds)
    results[name] = runner.run(agent, grid, N_STEPS, n_records=50)
print(grid.n_members, "members per run; member -> MDP", grid.mdp_index, " seed", grid.seeds)
print("MDP labels (for the CSV):", grid.mdp_labels[0][:60], "...")

# %% [markdown]
# `result.column(name)` returns one column of the reference's CSV as an array `[records, members]`; `result.steps`
# holds the step counts of the records (`write_csv` writes them all). The paper's score of an agent is the
# normalised cumulative regret after `T` steps divided by `T`.

# %%
res = results["q_learning_continuous"]
print("records at steps", res.steps[:3], "...", res.steps[-1], "| column shape", res.column("cumulative_regret").shape)
print("normalised regret per step after", N_STEPS, "steps (mean ± std over seeds)")
print(f"{'agent':24s}" + "".join(f"{f'{m.n_states} states':>18s}" for m in mdps))
for name, r in results.items():
    score = r.column("normalized_cumulative_regret")[-1] / N_STEPS
    cells = [f"{score[r.grid.mdp_index == m].mean():.3f} ± {score[r.grid.mdp_index == m].std():.3f}"
             for m in range(len(mdps))]
    print(f"{name:24s}" + "".join(f"{c:>18s}" for c in cells))

# %% [markdown]
# ## 4. The indicators are exact
#
# Every result also carries the reference's baseline columns (random, worst and optimal policies), computed from the
# exact gains. The random agent's policy estimate is the uniform policy, so its logged regret must be the random
# baseline, up to float32 round-off, for every seed: nothing is sampled.

# %%
r = results["random_continuous"]
ours, baseline = r.column("normalized_cumulative_regret"), r.column("random_normalized_cumulative_regret")
np.testing.assert_allclose(ours, baseline, rtol=1e-4)
print("random agent == random baseline; final normalised cumulative regret per member:\n", ours[-1])
print(f"member 0: sampled cumulative reward {r.column('cumulative_reward')[-1, 0]:.1f}, "
      f"expected {r.column('cumulative_expected_reward')[-1, 0]:.1f}")

# %% [markdown]
# ## 5. An agent against the random agent
#
# Normalised cumulative regret on the 8-state RiverSwim: the mean over the 6 seeds with a 95% bootstrap band
# (`hardness.analysis.plotting.bootstrap_ci`, seeds as the resampling unit). The random agent's band is empty: its exact
# regret does not depend on the seed.

# %%
fig, ax = plt.subplots(figsize=(6, 3.6))
for name, r in results.items():
    curves = r.column("normalized_cumulative_regret")[:, r.grid.mdp_index == 0].T     # [seeds, records]
    mean, lo, hi = bootstrap_ci(curves)
    (line,) = ax.plot(r.steps, mean, label=name)
    ax.fill_between(r.steps, lo, hi, color=line.get_color(), alpha=0.25, linewidth=0)
ax.set_xlabel("steps")
ax.set_ylabel("normalised cumulative regret")
ax.set_title(mdps[0].info.family + f" (continuous, {mdps[0].n_states} states, p_rand=0.3)", fontsize=9)
ax.legend(fontsize=8)
ax.grid(alpha=0.3)
plt.close(fig)
fig

# %% [markdown]
# ## 6. Checkpoints and resuming
#
# With `checkpoint_path`, `runner.run` saves the loop's state after every chunk (and `csv_path` appends the records);
# calling it again with the same arguments continues from the checkpoint. Every random draw comes from the member's
# key folded with the step index, so an interrupted and resumed run gives exactly the uninterrupted numbers.
# (`stop_after_chunks` simulates the interruption.)

# %%
workdir = Path(tempfile.mkdtemp())
grid = runner.product(mdps, [q_agent.default_hparams], seeds)
kwargs = dict(n_records=50, checkpoint_path=workdir / "run.npz", csv_path=workdir / "run.csv")
part = runner.run(q_agent, grid, N_STEPS, stop_after_chunks=5, **kwargs)
print("interrupted; last record at step", part.steps[-1], "| checkpoint written:", (workdir / "run.npz").exists())
resumed = runner.run(q_agent, grid, N_STEPS, **kwargs)
np.testing.assert_array_equal(resumed.values, results["q_learning_continuous"].values)
np.testing.assert_array_equal(resumed.agent_state.Q_hat, results["q_learning_continuous"].agent_state.Q_hat)
print("resumed to", resumed.steps[-1], "steps: identical to the uninterrupted run;",
      sum(1 for _ in open(workdir / "run.csv")) - 1, "CSV rows")

# %% [markdown]
# ## 7. A hyperparameter search as one batch
#
# `search_spaces.sample_candidates(agent, key, n)` draws `n` hyperparameter sets from the reference's search space
# (candidate 0 is the default), stacked along a leading axis. Because hyperparameters are pytree leaves, anything that
# takes one set vmaps over the stack, e.g. the constants Q-learning derives from them at `init` (a small `h_weight`
# floors its horizon `H` at 1, i.e. a discount of 0: a myopic learner):

# %%
n_candidates = 6
candidates = search_spaces.sample_candidates(q_agent, jax.random.key(1), n_candidates)
print(search_spaces.search_space(q_agent))
init_all = jax.vmap(q_agent.init, in_axes=(None, None, 0))(jax.random.key(0), spec_of(river, N_STEPS), candidates)
for i in range(n_candidates):
    print(f"candidate {i}: h_weight {candidates.h_weight[i]:.3f}  span_approx_weight "
          f"{candidates.span_approx_weight[i]:.3f}  min_at {candidates.min_at[i]:.3f}  ->  "
          f"H {float(init_all.H[i]):7.2f}  gamma {float(init_all.gamma[i]):.4f}")

# %% [markdown]
# The search itself is one lockstep run of candidates × MDPs × seeds. `runner.product` takes a list of sets, so the
# stack is split into its members first. Here each candidate meets each MDP with one seed, which makes a batch of the
# same shape as the Q-learning run of section 3, so the runner reuses that compiled program (a real search would use
# more seeds and longer runs).

# %%
candidate_list = [jax.tree.map(lambda x: x[i], candidates) for i in range(n_candidates)]
search = runner.run(q_agent, runner.product(mdps, candidate_list, seeds=[0]), N_STEPS, n_records=50)
score = search.column("normalized_cumulative_regret")[-1] / N_STEPS
per_candidate = np.array([score[search.grid.hparams_index == i].mean() for i in range(n_candidates)])
for i in np.argsort(per_candidate):
    print(f"candidate {i}: normalised regret per step {per_candidate[i]:.4f} (mean over the two MDPs)"
          + ("  <- the default" if i == 0 else ""))
