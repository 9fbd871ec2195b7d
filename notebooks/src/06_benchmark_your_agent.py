"""Source of notebooks/06_benchmark_your_agent.ipynb (build: PYTHONPATH=$PWD python scripts/build_notebooks.py)."""

# %% [markdown]
# # Benchmark your own agent
#
# From an empty file to your agent's row in the benchmark's table, beside the shipped agents' committed results,
# without running them again (docs/guide/own_agent.md):
#
# 1. write an agent in a module of your own and register it (`agents.register`);
# 2. run it on the quick benchmark with `baseline="committed"` (the command line: `jaxmdp-benchmark run --quick
#    --agents my_agents:EPSILON_GREEDY --baseline committed --out DIR`);
# 3. read the table and the figure; see what happens when the protocol differs.
#
# To keep it short the run keeps two MDPs of the quick-test set (`only`); the shipped agents' committed quick-test
# results hold every MDP, so they are comparable with any subset.

# %%
import sys
from pathlib import Path

import agents
from hardness.benchmark import report, run

# %% [markdown]
# ## 1. The agent, in a file of your own
#
# An epsilon-greedy Q-learner for episodic MDPs: four pure functions on one member's pytrees (the runner vmaps them)
# and a registration with its search space (uniform ranges, for `jaxmdp-benchmark tune`). The notebook writes the
# file into its working folder and imports it, as you would import your module.

# %%
MODULE = """import jax
import jax.numpy as jnp

import agents
from jaxmdp import struct
from jaxmdp.agent_interface import Agent


class HParams(struct.PyTreeNode):
    epsilon: float = 0.1
    learning_rate: float = 0.5


class State(struct.PyTreeNode):
    q: jax.Array
    action_mask: jax.Array
    hparams: HParams


def init(key, spec, hparams):
    h = jnp.arange(spec.H, dtype=jnp.float32)[:, None, None]
    q = jnp.broadcast_to(spec.H - h, (spec.H, spec.n_states, spec.n_actions))
    return State(q=q, action_mask=spec.action_mask, hparams=hparams)


def _greedy(q, mask):
    return jnp.argmax(jnp.where(mask, q, -jnp.inf), axis=-1)


def act(key, state, obs, h):
    explore_key, action_key = jax.random.split(key)
    p = state.action_mask / state.action_mask.sum()
    random_action = jax.random.choice(action_key, p.shape[0], p=p)
    explore = jax.random.uniform(explore_key) < state.hparams.epsilon
    return jnp.where(explore, random_action, _greedy(state.q[h, obs], state.action_mask)).astype(jnp.int32)


def update(state, t):
    H = state.q.shape[0]
    next_q = jnp.where(state.action_mask, state.q[jnp.minimum(t.h + 1, H - 1), t.next_obs], -jnp.inf)
    target = t.reward + jnp.where(t.terminated, 0.0, next_q.max())
    old = state.q[t.h, t.obs, t.action]
    return state.replace(q=state.q.at[t.h, t.obs, t.action].set(old + state.hparams.learning_rate * (target - old)))


def policy(state):
    return jax.nn.one_hot(_greedy(state.q, state.action_mask), state.q.shape[-1])


EPSILON_GREEDY = Agent(name="epsilon_greedy_q", episodic=True, default_hparams=HParams(), init=init, act=act,
                       update=update, policy=policy)
agents.register(EPSILON_GREEDY, search_space={"epsilon": (0.01, 0.3), "learning_rate": (0.05, 1.0)})"""
Path("my_agents.py").write_text(MODULE)
sys.path.insert(0, str(Path.cwd()))
import my_agents  # noqa: E402  (registers epsilon_greedy_q)

agents.get("epsilon_greedy_q").name, agents.names(episodic=True, observations=("state",))

# %% [markdown]
# ## 2. The quick benchmark, beside the committed results
#
# Only your agent runs. `baseline="committed"` reads the shipped agents' committed results (package data) and checks
# that they were made under this run's protocol: steps, seeds, log period, emission, agent rules, indicators and the
# hyperparameters `--hparams` gives them.

# %%
config = run.quick_config(agents=("epsilon_greedy_q",), only=("RiverSwim", "DeepSea"))
summary = run.run_benchmark(config, "mine", baseline="committed", progress=False)
summary.ran

# %%
s = report.summarize("mine", "committed")
print(report.markdown_table(s, "episodic quick test"))

# %%
report.hardness_figure(s, "episodic quick test")

# %% [markdown]
# ## 3. Another protocol is refused
#
# At 500 steps no committed result is comparable: the run stops before it starts and names what differs. Run the
# shipped agents once at that protocol and name their folder as the baseline instead.

# %%
try:
    run.run_benchmark(run.quick_config(agents=("epsilon_greedy_q",), only=("RiverSwim",), n_steps=500), "other",
                      baseline="committed", progress=False)
except ValueError as err:
    print(str(err)[:400])
assert not Path("other").exists()
