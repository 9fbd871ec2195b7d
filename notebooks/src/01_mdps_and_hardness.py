"""Source of notebooks/01_mdps_and_hardness.ipynb (build: PYTHONPATH=$PWD python scripts/build_notebooks.py)."""

# %% [markdown]
# # MDPs and their hardness with `jaxmdp`
#
# `jaxmdp` holds a finite MDP as a pytree of dense arrays, so that `jit` and `vmap` work on it like on any other
# JAX data. This notebook goes from building MDPs to the hardness measures of *Hardness in Markov Decision Processes:
# Theory and Practice* (Conserva & Rauber, NeurIPS 2022):
#
# 1. MDP families with `jaxmdp.make`, and a state rendered as text;
# 2. an MDP from your own arrays with `jaxmdp.custom_mdp`;
# 3. communication classes;
# 4. reference values (optimal, worst and random policies);
# 5. a `p_rand` sweep as one `vmap` of a kernel transform;
# 6. `hardness.measures` on a stacked (padded) batch;
# 7. the paper's definitions against the reference package's numbers (`variant="colosseum"`);
# 8. a small hardness scenario and its figure.
#
# Everything runs on a laptop CPU in about a minute; sizes are kept small on purpose.

# %%
import tempfile
from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import hardness  # importing jaxmdp (hardness does) before any JAX computation lets it set an XLA flag it needs
import jaxmdp
from hardness.analysis import plotting, scenarios

np.set_printoptions(precision=4, suppress=True)

# %% [markdown]
# ## 1. Families
#
# `jaxmdp.families()` lists the registered families. `make(name, episodic=..., seed=..., **params)` builds one
# (host side, once); the result is an `MDP`: `T[S, A, S]`, `R[S, A]`, `P0[S]`, the per-transition reward
# distributions, successor lists `succ/succ_p[S, A, K]` and masks. Static metadata (node labels, construction
# parameters) sits in `mdp.info` and never enters a trace.

# %%
print(jaxmdp.families())
river = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=6, randomize_actions=False)
print(river)
print("T", river.T.shape, "R", river.R.shape, "succ", river.succ.shape, "P0", river.P0)
print("states:", river.info.node_labels)
print("mean reward of (state, action):\n", river.R)

# %% [markdown]
# Every family can render a state as text (the paper's App. C representations): `A` is the agent; RiverSwim marks
# its start `S` and goal `G`, SimpleGrid its good `+` and bad `-` cells, FrozenLake its frozen cells `F`, holes `H`
# and goal `G`. Episodic MDPs can add the in-episode time as a header.

# %%
print(jaxmdp.render(river, 0), "\n")
print(jaxmdp.render(river, 4), "\n")
grid = jaxmdp.make("SimpleGrid", episodic=True, seed=0, size=4)
print(grid)
print(jaxmdp.render(grid, 0, h=0), "\n")
lake = jaxmdp.make("FrozenLake", episodic=False, seed=0, size=4, p_frozen=0.8)
print(lake, "start state:", lake.info.node_labels[int(jnp.argmax(lake.P0))])
print(jaxmdp.render(lake, int(jnp.argmax(lake.P0))))

# %% [markdown]
# Misspelt names and parameters fail early, with a hint:

# %%
for bad in (dict(name="RiverSwimm"), dict(name="RiverSwim", sise=5)):
    try:
        jaxmdp.make(episodic=False, seed=0, **bad)
    except ValueError as err:
        print("ValueError:", err)

# %% [markdown]
# ## 2. An MDP from arrays
#
# `custom_mdp(T, R, P0, H)` validates the arrays and builds the same pytree. Here a three-state "safe or risky"
# MDP: from state 0, action 0 moves to state 1, whose way back to 0 pays 0.5; action 1 reaches state 2 only with
# probability 0.5 (otherwise it stays in 0), and the way back from state 2 pays a Beta reward of mean 0.8. Rewards
# can depend on the next state (`reward_mean[s, a, s']`); a positive `reward_conc` makes them
# Beta(mean·conc, (1-mean)·conc), zero a point mass at the mean.

# %%
S, A = 3, 2
T = np.zeros((S, A, S))
T[0, 0, 1] = 1.0                      # safe
T[0, 1, [0, 2]] = 0.5                 # risky: 50% stay, 50% reach state 2
T[1, :, 0] = 1.0                      # both states return to 0
T[2, :, 0] = 1.0
reward_mean = np.zeros((S, A, S))
reward_mean[1, :, 0] = 0.5
reward_mean[2, :, 0] = 0.8
reward_conc = np.where(reward_mean == 0.8, 4.0, 0.0)     # Beta(3.2, 0.8) out of state 2
custom = jaxmdp.custom_mdp(T, reward_mean=reward_mean, reward_conc=reward_conc)
print(custom)
print("R =\n", custom.R)

try:
    jaxmdp.custom_mdp(T * 0.9, R=np.zeros((S, A)))
except ValueError as err:
    print("ValueError:", err)

# %% [markdown]
# ## 3. Communication classes
#
# `communication_class` classifies an MDP as the reference does (ergodic, communicating, weakly communicating) and
# returns `MULTICHAIN` where the reference would crash. A random-action probability makes RiverSwim ergodic; an
# absorbing state makes the rest transient.

# %%
absorbing = T.copy()
absorbing[2] = 0.0
absorbing[2, :, 2] = 1.0              # state 2 never leaves: 0 and 1 become transient
two_traps = absorbing.copy()
two_traps[1] = 0.0
two_traps[1, :, 1] = 1.0              # and state 1 too: two closed classes
for label, mdp in [
    ("RiverSwim", river),
    ("RiverSwim, p_rand=0.1", jaxmdp.apply_p_rand(river, 0.1)),
    ("safe or risky", custom),
    ("absorbing state 2", jaxmdp.custom_mdp(absorbing, np.zeros((S, A)))),
    ("two absorbing states", jaxmdp.custom_mdp(two_traps, np.zeros((S, A)))),
]:
    print(f"{label:24s} {jaxmdp.communication_class(mdp).name}")

# %% [markdown]
# ## 4. Reference values
#
# `reference_values(mdp)` gives the values of the optimal, worst and uniformly random policies, the numbers regrets
# are measured against: long-run average rewards (gains) for continuous MDPs, expected `H`-step returns from `P0`
# for episodic ones. It is a pure function: wrap it in `jax.jit` (it is much slower op by op) and strip the
# metadata first so that MDPs of the same shapes share one compilation.

# %%
values_fn = jax.jit(jaxmdp.reference_values, static_argnames="variant")
for label, mdp in [("SimpleGrid episodic (return)", grid), ("safe or risky (gain)", custom)]:
    v = values_fn(mdp.strip())
    print(f"{label:30s} optimal {float(v.optimal):.4f}  worst {float(v.worst):.4f}  random {float(v.random):.4f}")
print("safe or risky, optimal action per state:", np.asarray(v.optimal_policy).argmax(-1))

# %% [markdown]
# Safe pays 0.5 every other step (gain 0.25); risky pays 0.8 (in expectation) once every 3 steps on average (gain
# 0.2667): the optimal policy takes the risk in state 0.
#
# ## 5. A `p_rand` sweep is one `vmap`
#
# `apply_p_rand(mdp, p)` replaces the chosen action by a uniformly random one with probability `p` (paper App. C).
# It is jittable and keeps every shape fixed, so a whole sweep is one `vmap` over `p`, and anything downstream (values,
# measures) vmaps over the result.

# %%
p_rand = jnp.linspace(0.0, 0.9, 10)
sweep = jax.vmap(jaxmdp.apply_p_rand, in_axes=(None, 0))(river, p_rand)
print(sweep)                                              # a batch of 10 MDPs, T is [10, S, A, S]
gains = jax.jit(jax.vmap(jaxmdp.reference_values))(sweep.strip())
for p, opt, rnd in zip(p_rand, gains.optimal, gains.random):
    print(f"p_rand={float(p):.1f}  optimal gain {float(opt):.4f}  random gain {float(rnd):.4f}")

# %% [markdown]
# The transform gives the same MDP as building with `p_rand` from scratch, up to the order in which the
# construction enumerates states (`state_permutation` matches them by node label):

# %%
scratch = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=6, randomize_actions=False, p_rand=0.3)
member = jax.tree.map(lambda x: x[3], sweep)              # p_rand = 0.3
aligned = jaxmdp.permute_states(member, jaxmdp.state_permutation(member, scratch))
np.testing.assert_allclose(aligned.T, scratch.T, atol=1e-6)
np.testing.assert_allclose(aligned.R, scratch.R, atol=1e-6)
print("transform == construction from scratch")

# %% [markdown]
# ## 6. Hardness measures on a stacked batch
#
# `hardness.measures(mdp)` computes the three measures of paper §2.2: the diameter, the environmental value norm and
# the (regularised) sum of reciprocal sub-optimality gaps, each a `MeasureResult(value, converged, finite)`.
# MDPs of different sizes are padded to common shapes by `jaxmdp.stack` (padded states are unreachable, padded
# actions copy action 0) and the whole batch runs as one compiled `vmap`. Padding changes no value:

# %%
members = [river, jaxmdp.make("FrozenLake", episodic=False, seed=0, size=4, p_frozen=0.8, p_lazy=0.1)]
batch = jaxmdp.stack(members)
print(batch)
batched = jax.jit(jax.vmap(hardness.measures))(batch)
names = ("diameter", "value_norm", "sum_reciprocal_gaps")
for i, mdp in enumerate(members):
    alone = hardness.measures(mdp)
    for name in names:
        a, b = float(getattr(alone, name).value), float(getattr(batched, name).value[i])
        print(f"{mdp.info.family:10s} {name:20s} alone {a:10.4f}   in the padded batch {b:10.4f}")
        np.testing.assert_allclose(b, a, rtol=1e-5)

# %% [markdown]
# ## 7. The paper's definitions and the reference package's numbers
#
# Where the reference package (Colosseum) computes something other than the paper's definition, `variant="paper"`
# (the default) follows the paper and `variant="colosseum"` reproduces the package's numbers. The MDP below is the
# one stored in the reference data file `ref04_RiverSwim_episodic`, which the tests check against (an episodic
# RiverSwim; the numbers the Colosseum package computed for it are typed in). For episodic MDPs the two diameters
# are different quantities (the paper's is the diameter of the time-augmented MDP), and the package's value norm
# centres each next value on the next state's own expected value instead of on `E[V(s') | s, a]`, so it is not a
# standard deviation. The gap sums agree: both variants use the package's regularised sum `Σ 1 / (Δ + 0.1)`.

# %%
fixture = jaxmdp.make("RiverSwim", episodic=True, seed=3, size=10, make_reward_stochastic=True, p_lazy=0.1,
                      randomize_actions=False)
colosseum_package = {"diameter": 25.81036376953125, "value_norm": 0.8175380825996399,
                     "sum_reciprocal_gaps": 959.7810668945312}
paper = hardness.measures(fixture)
colosseum = hardness.measures(fixture, variant="colosseum")
print(f"{'':22s}{'paper':>10s}{'colosseum':>12s}{'package':>12s}")
for name in names:
    print(f"{name:22s}{float(getattr(paper, name).value):10.4f}{float(getattr(colosseum, name).value):12.4f}"
          f"{colosseum_package[name]:12.4f}")

# %% [markdown]
# ## 8. A hardness scenario
#
# `hardness.analysis.scenarios.run_scenario(scenario, family, ...)` runs one of the paper's four scenarios (1: `p_rand`,
# 2: `p_lazy`, 3: size, 4: size with `p_rand = 0.1`) over seeds and values in one batched call and normalises every
# measure to [0, 1] across the sweep (paper App. E). `hardness.analysis.plotting.plot_scenario` draws the mean over
# seeds with a 95% bootstrap band and writes a PNG (the figure is shown below by loading that file). FrozenLake maps
# depend on the seed, so the bands are not empty.

# %%
result = scenarios.run_scenario(1, "FrozenLake", episodic=False, seeds=(0, 1, 2),
                                values=(0.0, 0.1, 0.2, 0.3, 0.4, 0.5), params=dict(size=4, p_frozen=0.8))
print("states per seed:", result.n_states[:, 0])
for name in names:
    print(f"{name:20s} raw, seed 0: {result.raw[name][0]}")

png = plotting.plot_scenario(result.x, result.normalized, Path(tempfile.mkdtemp()) / "scenario1.png",
                             xlabel="p_rand", title="FrozenLake (continuous, size 4): scenario 1")


class PNG:
    """Shows a PNG file in a notebook (Jupyter displays any object with ``_repr_png_``)."""

    def __init__(self, path):
        self.data = Path(path).read_bytes()

    def _repr_png_(self):
        return self.data

    def __repr__(self):
        return f"<PNG, {len(self.data)} bytes>"


PNG(png)
