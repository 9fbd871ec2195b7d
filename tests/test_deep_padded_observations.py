"""Deep agents on zero-padded observations (:func:`jaxmdp.pad_observations`): the deep benchmark runs MDPs whose
emissions differ in shape as one batch, padded to one shape, and each agent must learn there as it would on its own
observations (paper App. G; docs/benchmark.md §5).

Two properties, each of which fails on an agent that ignores the mask:

* **The initialisation has the unpadded distribution**: the input layer's kept rows are distributed as a draw at the
  true fan-in (two-sample Kolmogorov-Smirnov test against unpadded initialisations; the same test rejects the
  initialisation without the mask's rescaling), and its padded rows are zero.
* **From the same parameters, the same learning**: an agent whose state is the unpadded agent's with zero rows
  appended takes the same actions for hundreds of steps on the padded BlockMDP and ends with the same parameters (to
  rounding), its padded rows still zero (they meet only zero inputs, so they get no gradient).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import agents
import jaxmdp
from jaxmdp.experiment.agent_interface import Transition, spec_of

# RiverSwim's state_info has one component (the position); padded to 4, three quarters of the input are padding.
WIDTH, PADDED = 1, 4
#: Where each agent's input layer sits in its parameters (the MLP torso of the actor-critics).
INPUT = {"dqn_continuous": ("Dense_0",), "boot_dqn_continuous": ("Dense_0",),
         "actor_critic_continuous": ("MLP_0", "Dense_0"), "actor_critic_rnn_continuous": ("MLP_0", "Dense_0")}
#: Small replay buffers: these tests look at parameters, not at learning curves.
SMALL = {"dqn_continuous": dict(replay_capacity=400), "boot_dqn_continuous": dict(replay_capacity=400),
         "actor_critic_continuous": {}, "actor_critic_rnn_continuous": {}}


@functools.cache
def blocks() -> tuple[jaxmdp.BlockMDP, jaxmdp.BlockMDP]:
    block = jaxmdp.block_mdp(jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5), "state_info")
    assert block.obs_shape == (WIDTH,)
    return block, jaxmdp.pad_observations(block, (PADDED,))


def agent_and_hparams(name: str):
    agent = agents.get(name)
    return agent, agent.default_hparams.replace(**SMALL[name])


def input_kernel(params, name: str, xp=np) -> np.ndarray:
    """The input layer's kernel of ``name``'s parameters, as an ``xp`` array (numpy, or jax.numpy under ``jit``)."""
    node = params["params"]
    for key in INPUT[name]:
        node = node[key]
    return xp.asarray(node["kernel"])


@functools.cache
def initialise(name: str):
    """``init(keys, spec)``: the jitted, vmapped ``init`` of ``name`` (the spec an argument: one compilation per
    observation shape)."""
    agent, hp = agent_and_hparams(name)
    return jax.jit(jax.vmap(lambda k, spec: agent.init(k, spec, hp), in_axes=(0, None)))


def kernels(name: str, block: jaxmdp.BlockMDP, n_keys: int, *, rescale: bool = True) -> np.ndarray:
    """The input-layer kernels of ``n_keys`` initialisations on ``block``, ``[n_keys, (heads,) d, width]``; with
    ``rescale=False``, the padded block's mask replaced by ones (the initialisation of an agent that ignores it)."""
    spec = spec_of(block, 100)
    if not rescale:
        spec = spec.replace(observation_mask=jnp.ones_like(spec.observation_mask))
    states = initialise(name)(jax.random.split(jax.random.key(11), n_keys), spec)
    return input_kernel(states.params, name)


@pytest.mark.parametrize("name", ["dqn_continuous", "boot_dqn_continuous", "actor_critic_continuous"])
def test_input_layer_initialisation_has_the_unpadded_distribution(name):
    # The RNN actor-critic initialises through the same function as the actor-critic (initial_state).
    plain, padded = blocks()
    n_keys = 20 if name.startswith("boot") else 300  # BootDQN: 20 heads per key
    want = kernels(name, plain, n_keys).reshape(-1)
    got = kernels(name, padded, n_keys)
    np.testing.assert_array_equal(got[..., WIDTH:, :], 0.0)
    kept = got[..., :WIDTH, :].reshape(-1)
    assert kept.size == want.size >= 15_000
    # Kolmogorov-Smirnov, two independent samples of iid entries (other keys): a false failure has probability 1e-6.
    assert stats.ks_2samp(kept, want).pvalue > 1e-6
    # The test's power: without the mask's rescaling the kept rows have a quarter of the variance, and it sees that.
    unscaled = kernels(name, padded, n_keys, rescale=False)[..., :WIDTH, :].reshape(-1)
    assert stats.ks_2samp(unscaled, want).pvalue < 1e-20


def embed(small, like):
    """``small`` (a state of the unpadded agent) with every leaf zero-padded to the shape of ``like``'s leaf."""
    return jax.tree.map(
        lambda a, b: a if a.shape == b.shape else jnp.pad(a, [(0, n - m) for m, n in zip(a.shape, b.shape)]),
        small, like)


def padded(x: jax.Array) -> jax.Array:
    return jnp.pad(x, (0, PADDED - WIDTH))


def largest_difference(big, small) -> jax.Array:
    """The largest ``|big - small|`` over the parameters, ``big``'s leaves cut to ``small``'s shapes."""
    pairs = zip(jax.tree.leaves(big.params), jax.tree.leaves(small.params))
    return jnp.max(jnp.stack([jnp.max(jnp.abs(b[tuple(slice(0, n) for n in a.shape)] - a)) for b, a in pairs]))


@functools.partial(jax.jit, static_argnames=("agent", "n_steps"))
def play(agent, block, plain, like, key, n_steps):
    """``n_steps`` of act -> step -> update (-> plan when asked) on ``block`` by the unpadded agent ``plain``; at
    every step the same step, from the same state embedded in ``like``'s shapes (:func:`embed`), by the agent on
    padded observations. Per step: both agents' actions, whether both ask to plan, the largest difference of the
    parameters after the step and the largest entry of the padded input rows."""
    k_reset, key = jax.random.split(key)
    obs, env = jaxmdp.reset(k_reset, block)

    def body(carry, t):
        plain, env, obs = carry
        state = embed(plain, like)
        k_act, k_step, k_plan = jax.random.split(jax.random.fold_in(key, t), 3)
        a = agent.act(k_act, plain, obs, env.h)
        a_padded = agent.act(k_act, state, padded(obs), env.h)
        obs2, env2, r, term, _, info = jaxmdp.step(k_step, env, a, block)
        tr = Transition(obs=obs, action=a, reward=r, next_obs=info["final_observation"], h=env.h, terminated=term)
        plain = agent.update(plain, tr)
        state = agent.update(state, tr.replace(obs=padded(tr.obs), next_obs=padded(tr.next_obs)))
        need = agent.needs_plan(plain)
        same_need = need == agent.needs_plan(state)
        plain, state = jax.lax.cond(need, lambda s: tuple(agent.plan(k_plan, x) for x in s), lambda s: s,
                                    (plain, state))
        padding = jnp.max(jnp.abs(input_kernel(state.params, agent.name, xp=jnp)[..., WIDTH:, :]))
        return (plain, env2, obs2), (a, a_padded, same_need, largest_difference(state, plain), padding)

    (plain, _, _), out = jax.lax.scan(body, (plain, env, obs), jnp.arange(n_steps))
    return plain, *out


@pytest.mark.parametrize("name", [
    "dqn_continuous",
    "actor_critic_continuous",
    pytest.param("boot_dqn_continuous", marks=pytest.mark.nightly),  # by default: its initialisation test above
    pytest.param("actor_critic_rnn_continuous", marks=pytest.mark.nightly),  # by default: actor_critic's
])
def test_from_the_same_parameters_the_padded_agent_learns_as_the_unpadded_one(name):
    plain, padded_block = blocks()
    agent, hp = agent_and_hparams(name)
    key = jax.random.key(3)
    small = agent.init(key, spec_of(plain, 400), hp)
    like = agent.init(key, spec_of(padded_block, 400), hp)
    np.testing.assert_array_equal(embed(small, like).observations, padded_block.emissions)
    end, actions, padded_actions, same_need, difference, padding = play(agent, plain, small, like, key, 400)
    assert len(set(np.asarray(actions).tolist())) == 2  # both actions taken: the comparison covers learning
    moved = np.abs(input_kernel(end.params, name) - input_kernel(small.params, name)).max()
    assert moved > 5e-3, moved  # the parameters were trained (Adam steps of 1e-3)
    np.testing.assert_array_equal(padded_actions, actions)
    assert bool(np.all(same_need))
    np.testing.assert_array_equal(padding, 0.0)  # no gradient ever reaches the padded rows
    # Adam's steps are 1e-3 (its learning rate): a wrong update differs by that much in some parameter.
    assert float(np.max(difference)) < 1e-6, np.max(difference)
