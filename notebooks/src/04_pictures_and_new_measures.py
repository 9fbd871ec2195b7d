"""Source of notebooks/04_pictures_and_new_measures.ipynb (build: PYTHONPATH=$PWD python scripts/build_notebooks.py)."""

# %% [markdown]
# # Pictures of MDPs, and the measures the paper could not compute
#
# 1. `jaxmdp.plotting`: an MDP as a graph on its family's layout, a policy's Markov chain with its stationary
#    distribution, the optimal values and a run's state-visitation counts;
# 2. two measures that the paper's Table 1 marks "?": the mixing time of the optimal policy's chain
#    (`hardness.mixing_time`) and the distribution mismatch coefficient (`hardness.distribution_mismatch`), and how
#    they move with `p_rand`, `p_lazy` and the size;
# 3. rank correlations, the numbers behind `scripts/measure_evaluation.py` (paper §2.3's completeness).
#
# Every picture is a `matplotlib.figure.Figure` (no pyplot state); `fig.savefig(path)` writes it.

# %%
import jax
import jax.numpy as jnp
import numpy as np
from matplotlib.figure import Figure

import hardness
import jaxmdp
import jaxmdp.plotting as plotting
from agents import RANDOM_CONTINUOUS
from hardness.analysis import measure_evaluation
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment import runner

# %% [markdown]
# ## 1. Pictures
#
# The MDP graph: an edge wherever some action leads, wider when a uniformly random action takes it more often,
# coloured by the transition's expected reward. MiniGrid states are (cell, facing direction): each cell holds four
# nodes, each placed towards the direction it faces. The start state has a thick outline.

# %%
grid_mdp = jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=5)
plotting.draw_mdp(grid_mdp)

# %%
river = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=6, p_rand=0.1)
plotting.draw_mdp(river)

# %% [markdown]
# The optimal policy's Markov chain (the default policy of `draw_markov_chain`), nodes coloured by its stationary
# distribution. On MiniGridEmpty the optimal agent walks to the goal and then turns on it for ever (turning on the
# goal keeps paying): a chain of period 2 on the goal cell, which matters for the mixing time below.

# %%
fig = Figure(figsize=(15, 6), layout="constrained")
left, right = fig.subplots(1, 2, width_ratios=[1.4, 1])
plotting.draw_markov_chain(grid_mdp, ax=left)
plotting.draw_markov_chain(river, ax=right)
fig

# %% [markdown]
# The optimal values on the layout: here `V*_0` of an episodic DeepSea (the values at the episode's first step).

# %%
deep_sea = jaxmdp.make("DeepSea", episodic=True, seed=0, size=6)
plotting.draw_values(deep_sea, jaxmdp.reference_values(deep_sea).optimal_state_values)

# %% [markdown]
# State-visitation counts of a run: `runner.run(..., record_visits=True)` adds a per-member count of the states each
# member acted in (`RunResult.visits`, `[members, S]`); without the option the loop computes nothing for it. Here the
# uniformly random agent, three seeds on the MiniGrid, summed over the seeds.

# %%
N_VISIT_STEPS = 3_000
run = runner.run(RANDOM_CONTINUOUS, runner.product([grid_mdp], [RANDOM_CONTINUOUS.default_hparams], seeds=[0, 1, 2]),
                 N_VISIT_STEPS, n_records=2, record_visits=True)
np.testing.assert_array_equal(run.visits.sum(axis=1), [N_VISIT_STEPS] * 3)
plotting.draw_visits(grid_mdp, run.visits)

# %% [markdown]
# ## 2. Mixing time and distribution mismatch
#
# `hardness.mixing_time(mdp, policy=None, eps=0.25)` is `min t` with `max_s TV(P^t(s, .), P*(s, .)) <= eps` for the
# policy's chain (the optimal one by default), computed exactly by doubling and bisection on matrix powers. A periodic
# chain never mixes (`inf`); `lazy=True` measures the lazy chain `(I + P) / 2` instead. A two-state chain
# `[[1-p, p], [q, 1-q]]` has `d(t) = max(p, q) / (p + q) |1 - p - q|^t`:

# %%
p, q = 0.1, 0.3
closed_form = next(t for t in range(100) if max(p, q) / (p + q) * abs(1 - p - q) ** t <= 0.25)
two_state = hardness.mixing.chain_mixing_time(jnp.asarray([[1 - p, p], [q, 1 - q]]), 0.25)
print("two-state chain: t_mix =", float(two_state.value), "closed form:", closed_form)
print("MiniGridEmpty, optimal chain:", float(hardness.mixing_time(grid_mdp).value),
      "  its lazy chain:", float(hardness.mixing_time(grid_mdp, lazy=True).value))

# %% [markdown]
# `hardness.distribution_mismatch(mdp, policy, reference)` is `max_s d^pi(s) / mu(s)` (Kakade & Langford 2002;
# Agarwal et al. 2021): `d^pi` is the policy's state distribution from `P0` (stationary for a continuous MDP, or
# discounted with `gamma=...`; the in-episode average for an episodic one), `mu` a given distribution or another
# policy's. Against the uniformly random policy, DeepSea's optimal policy gives `2^(size-1)`: the random walk reaches
# the diagonal's last cell once in `2^(size-1)` episodes.

# %%
uniform = dp.uniform_policy(deep_sea)
print("DeepSea 6, optimal vs random:", float(hardness.distribution_mismatch(deep_sea, None, uniform).value))
print("identical policies:", float(hardness.distribution_mismatch(deep_sea, uniform, uniform).value))

# %% [markdown]
# How they move on the scenarios, for RiverSwim (continuous, size 10): `p_rand` and `p_lazy` are kernel transforms of
# one base MDP, so each sweep is one `vmap`; the size sweep builds one MDP per size. Both measures are jittable and
# vmappable like the paper's three.

# %%
base = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=10)
noise = jnp.linspace(0.0, 0.5, 6)


@jax.jit
def new_measures(mdps):
    def one(m):
        return hardness.mixing_time(m, lazy=True).value, hardness.distribution_mismatch(m, None, dp.uniform_policy(m)).value

    return jax.vmap(one)(mdps)


sweeps = {
    "p_rand": (noise, new_measures(jax.vmap(jaxmdp.apply_p_rand, in_axes=(None, 0))(base, noise))),
    "p_lazy": (noise, new_measures(jax.vmap(jaxmdp.apply_p_lazy, in_axes=(None, 0))(base, noise))),
}
sizes = [5, 10, 15, 20]
# One padded stack (padding changes neither measure), so one compiled program for every size.
by_size = jaxmdp.stack([jaxmdp.make("RiverSwim", episodic=False, seed=0, size=n) for n in sizes])
sweeps["size"] = (np.asarray(sizes), new_measures(by_size))

fig = Figure(figsize=(12, 3.4), layout="constrained")
for ax, (name, (x, (mix, dmc))) in zip(fig.subplots(1, 3), sweeps.items()):
    ax.plot(x, mix, "o-", label="mixing time (lazy chain)")
    ax.plot(x, dmc, "s-", label="mismatch: optimal vs random")
    ax.set_xlabel(name)
    ax.set_yscale("log")
fig.axes[0].legend(fontsize=8)
fig.suptitle("RiverSwim (continuous): the two new measures along the scenarios")
fig

# %% [markdown]
# ## 3. Rank correlations
#
# `scripts/measure_evaluation.py` reads a scenario sweep's table and reports, for every measure, Spearman's rho and
# Kendall's tau-b with the tuned near-optimal agent's regret, with bootstrap intervals over seeds (results on the four
# scenarios: docs/measures.md). The two statistics, on the size sweep above: both measures grow with the size, so
# both order the sizes identically.

# %%
mix, dmc = sweeps["size"][1]
print("Spearman(mixing time, mismatch) =", measure_evaluation.spearman(mix, dmc))
print("Kendall tau-b(mixing time, size) =", measure_evaluation.kendall_tau_b(mix, sizes))
