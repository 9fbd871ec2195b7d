"""The lockstep runner on BlockMDPs (paper §3.1, App. A.2): the same dynamics, rewards and exact indicators as on
the underlying MDP, observations handed to the agent as sampled, and agents of the wrong kind refused.

How we know: the random agent ignores what it observes, so its records on a BlockMDP must equal, bit for bit, its
records on the plain MDP for the same seeds (the noise has a stream of its own); a probe agent checks inside the
compiled loop that every transition's ``obs`` is the very sample of the previous transition's ``next_obs``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct

import agents
import jaxmdp
from jaxmdp.experiment import runner
from jaxmdp.experiment.agent_interface import Agent, spec_of

N_STEPS = 300


@pytest.fixture(scope="module")
def mdps():
    continuous = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, p_rand=0.1, randomize_actions=False,
                             make_reward_stochastic=True)
    episodic = jaxmdp.make("DeepSea", episodic=True, seed=0, size=4, p_rand=0.1, make_reward_stochastic=True)
    return {False: continuous, True: episodic}


@pytest.mark.nightly  # by default: test_agents_act_on_the_sample_they_were_handed
@pytest.mark.parametrize("episodic", [False, True])
def test_random_agent_records_equal_the_plain_mdp(mdps, episodic):
    mdp = mdps[episodic]
    agent = agents.get("random_episodic" if episodic else "random_continuous")
    block = jaxmdp.block_mdp(mdp, "state_info", "gaussian", scale=0.5)
    plain = runner.run(agent, runner.product([mdp], [agent.default_hparams], seeds=range(3)), N_STEPS,
                       log_period=10)
    noisy = runner.run(agent, runner.product([block], [agent.default_hparams], seeds=range(3)), N_STEPS,
                       log_period=10)
    np.testing.assert_array_equal(noisy.steps, plain.steps)
    np.testing.assert_array_equal(noisy.values, plain.values)
    assert np.all(plain.column("normalized_cumulative_regret")[-1] > 0)  # the comparison is not of zeros


class ProbeState(struct.PyTreeNode):
    last_next_obs: jax.Array
    ended: jax.Array  # the last transition ended an episode (its next_obs is then not acted on)
    started: jax.Array
    mismatches: jax.Array
    rows_off_table: jax.Array  # noiseless observations that are not the table row of any state
    n_states: int = struct.field(pytree_node=False)
    n_actions: int = struct.field(pytree_node=False)
    H: int | None = struct.field(pytree_node=False)
    table: jax.Array


def _probe(episodic: bool) -> Agent:
    """An emission agent that acts at random and counts, in its state, every transition whose ``obs`` differs from
    the previous transition's ``next_obs`` within an episode, and every observation off the emission table."""

    def init(key, spec, hp):
        obs_shape = spec.observations.shape[2 if episodic else 1:]
        return ProbeState(jnp.zeros(obs_shape, jnp.float32), jnp.bool_(False), jnp.bool_(False), jnp.int32(0),
                          jnp.int32(0), spec.n_states, spec.n_actions, spec.H, spec.observations)

    def act(key, state, obs, h):
        return jax.random.randint(key, (), 0, state.n_actions)

    def update(state, tr):
        same = jnp.all(tr.obs == state.last_next_obs)
        bad = state.started & ~state.ended & ~same
        rows = state.table.reshape((-1,) + tr.obs.shape)
        on_table = jnp.any(jnp.all((rows == tr.obs).reshape(rows.shape[0], -1), axis=1))
        return state.replace(last_next_obs=tr.next_obs, ended=tr.terminated, started=jnp.bool_(True),
                             mismatches=state.mismatches + bad, rows_off_table=state.rows_off_table + ~on_table)

    def policy(state):
        shape = (state.n_states, state.n_actions) if state.H is None else (state.H, state.n_states, state.n_actions)
        return jnp.full(shape, 1.0 / state.n_actions)

    return Agent(name="probe", episodic=episodic, default_hparams=(), init=init, act=act, update=update,
                 policy=policy, observation="emission")


@pytest.mark.parametrize("episodic", [False, True])
def test_agents_act_on_the_sample_they_were_handed(mdps, episodic):
    mdp = mdps[episodic]
    agent = _probe(episodic)
    keys = jax.random.split(jax.random.key(3), 2)
    # Noisy: the next observation must be passed on as sampled, not drawn again.
    noisy = jaxmdp.block_mdp(mdp, "state_info", "gaussian", scale=1.0)
    g = runner.grid([noisy, noisy], [agent.default_hparams] * 2, keys)
    result = _run(agent, g)
    assert np.all(np.asarray(result.agent_state.mismatches) == 0)
    assert np.all(np.asarray(result.agent_state.rows_off_table) > 0)  # noise really is there
    # Noiseless: every observation is a row of the table.
    clean = jaxmdp.block_mdp(mdp, "one_hot")
    result = _run(agent, runner.grid([clean, clean], [agent.default_hparams] * 2, keys))
    assert np.all(np.asarray(result.agent_state.rows_off_table) == 0)
    assert np.all(np.asarray(result.agent_state.mismatches) == 0)


def _run(agent, g):
    return runner.run(agent, g, N_STEPS)


def test_agents_of_the_wrong_kind_are_refused(mdps):
    mdp = mdps[False]
    q = agents.get("q_learning_continuous")
    with pytest.raises(ValueError, match="tabular.*BlockMDP"):
        runner.run(q, runner.product([jaxmdp.block_mdp(mdp)], [q.default_hparams], seeds=[0]), 10)
    dqn = agents.get("dqn_continuous")
    with pytest.raises(ValueError, match=r"deep agent.*jaxmdp.block_mdp\(mdp, 'state_info'\)"):
        runner.run(dqn, runner.product([mdp], [dqn.default_hparams], seeds=[0]), 10)


@pytest.mark.parametrize("episodic", [False, True])
def test_deep_agent_states_hold_no_typed_keys(mdps, episodic):
    """The runner returns (and checkpoints) agent states as NumPy arrays, which typed PRNG keys cannot become: an
    agent that keeps a key keeps its ``key_data`` (BootDQN did not, and failed at the end of every run)."""
    block = jaxmdp.block_mdp(mdps[episodic], "state_info")
    spec = spec_of(block, 100)
    for name, agent in agents.AGENTS.items():
        if agent.episodic != episodic:
            continue
        shapes = jax.eval_shape(agent.init, jax.random.key(0), spec, agent.default_hparams)
        typed = [x for x in jax.tree.leaves(shapes) if jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key)]
        assert not typed, name
