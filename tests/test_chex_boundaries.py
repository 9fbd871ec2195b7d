"""The chex assertions at the array boundaries (jaxmdp/_asserts.py): in each layer (dynamic programming, hardness
measures, agents' ``act``/``update``) an input of the wrong rank, shape or dtype raises chex's ``AssertionError`` at
trace time, eagerly and under ``jit``, with a message naming the argument; a correct input lowers to the same program
with the assertions disabled as with them enabled (they read static shapes only, so they cost nothing at run time);
and the host-side ``ValueError`` checks for user input are still what a user meets first."""

from __future__ import annotations

import importlib

import chex
import jax
import jax.numpy as jnp
import pytest

import agents
import hardness
import jaxmdp
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment.agent_interface import Transition, spec_of

_mixing = importlib.import_module("hardness.mixing")
_diameter = importlib.import_module("hardness.diameter")
_mismatch = importlib.import_module("hardness.mismatch")


@pytest.fixture(scope="module")
def mdp():
    return jaxmdp.make("RiverSwim", size=4, episodic=False, seed=0).strip()


@pytest.fixture(scope="module")
def stacked(mdp):
    return jaxmdp.stack([mdp, mdp])


def _raises(fn, *args, match: str):
    """``fn(*args)`` raises chex's AssertionError naming ``match``, called eagerly and under a fresh ``jit``."""
    for call in (fn, jax.jit(lambda *a: fn(*a))):
        with pytest.raises(AssertionError, match=r"\[Chex\].*" + match):
            call(*args)


def _same_program_without_asserts(fn, *args) -> None:
    """``fn`` (plain Python, traced afresh each time) lowers to the same text with chex's assertions off and on."""
    lowered = []
    for enabled in (False, True):
        (chex.enable_asserts if enabled else chex.disable_asserts)()
        try:
            lowered.append(jax.jit(lambda *a: fn(*a)).lower(*args).as_text())
        finally:
            chex.enable_asserts()
    assert lowered[0] == lowered[1]


def _tr(obs=0, next_obs=1, action=1, reward=0.5, h=0, **kw) -> Transition:
    as_array = lambda x, dt: x if isinstance(x, jax.Array) else jnp.asarray(x, dt)  # noqa: E731
    return Transition(obs=as_array(obs, jnp.int32), action=as_array(action, jnp.int32),
                      reward=as_array(reward, jnp.float32), next_obs=as_array(next_obs, jnp.int32),
                      h=as_array(h, jnp.int32), terminated=jnp.asarray(kw.get("terminated", False)))


# ---------------------------------------------------------------------------------------------------------------
# Dynamic programming
# ---------------------------------------------------------------------------------------------------------------


def test_dp_wrong_rank_shape_dtype(mdp, stacked):
    S, A = mdp.n_states, mdp.n_actions
    # A stacked MDP where one MDP is expected (the routine is vmapped over a stack, not given it).
    _raises(lambda m: dp.value_iteration(m, 0.9), stacked, match=r"model\.T: one MDP")
    # A policy of another MDP's shape.
    _raises(lambda m, pi: dp.policy_evaluation(m, pi, 0.9), mdp, jnp.ones((S, A + 1)) / (A + 1), match=r"pi: a policy")
    # Integer probabilities and rewards.
    P = jnp.eye(S, dtype=jnp.int32)
    _raises(lambda P, r: dp.discounted_chain_values(P, r, 0.9), P, jnp.ones(S), match=r"P: a chain of probab")
    _raises(lambda m, R: dp.value_iteration(m, 0.9, rewards=R), mdp, jnp.ones((S, A), jnp.int32), match=r"rewards")
    # Values of the wrong length, and actions given as a float array.
    _raises(lambda m, V: dp.q_values(m, V, 0.9), mdp, jnp.zeros(S + 1), match=r"V: values \[S\]")
    episodic = jaxmdp.make("RiverSwim", size=4, episodic=True, seed=0).strip()
    actions = jnp.zeros((episodic.H, S), jnp.float32)
    _raises(dp.finite_horizon_deterministic_evaluation, episodic, actions, match=r"actions: action indices")


def test_dp_value_errors_stay_first(mdp):
    # A dense kernel without rewards is refused with the ValueError naming the parameter, as before.
    with pytest.raises(ValueError, match="rewards must be given"):
        dp.value_iteration(mdp.T, 0.9)
    with pytest.raises(ValueError, match="H must be given"):
        dp.finite_horizon_value_iteration(mdp)


def test_dp_same_program(mdp):
    _same_program_without_asserts(lambda m: dp.value_iteration.__wrapped__(m, 0.9), mdp)
    _same_program_without_asserts(lambda m, pi: dp.gain_vector.__wrapped__(m, pi), mdp, dp.uniform_policy(mdp))


# ---------------------------------------------------------------------------------------------------------------
# Hardness measures
# ---------------------------------------------------------------------------------------------------------------


def test_measures_wrong_rank_shape_dtype(mdp, stacked):
    S = mdp.n_states
    _raises(lambda m: hardness.diameter(m).value, stacked, match=r"mdp\.T: one MDP")
    _raises(lambda m: hardness.value_norm(m).value, stacked, match=r"mdp\.T: one MDP")
    _raises(_mismatch.mismatch_ratio, jnp.ones(S) / S, jnp.ones(S + 1) / (S + 1), match=r"d and mu")
    _raises(lambda P: _mixing.chain_mixing_time(P).value, jnp.eye(S, dtype=jnp.int32), match=r"P: a chain of probab")
    _raises(lambda m: hardness.diameter(m).value, mdp.replace(succ=mdp.succ.astype(jnp.float32)),
            match=r"succ integer")


def test_measures_value_errors_stay_first(mdp):
    with pytest.raises(ValueError, match="policy must be a policy of shape"):
        hardness.mixing_time(mdp, jnp.ones((mdp.n_states, mdp.n_actions + 1)))
    with pytest.raises(ValueError, match="reference must be a distribution"):
        hardness.distribution_mismatch(mdp, None, jnp.ones(mdp.n_states + 1))


def test_measures_same_program(mdp):
    _same_program_without_asserts(lambda m: _diameter._diameter.__wrapped__(m, "paper", 1e-6, 1000, 8), mdp)
    P = dp.policy_matrix(mdp, dp.uniform_policy(mdp))
    _same_program_without_asserts(lambda P: _mixing.chain_mixing_time.__wrapped__(P, 0.25, None, 30), P)


# ---------------------------------------------------------------------------------------------------------------
# Agents
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["q_learning_episodic", "q_learning_continuous", "psrl_episodic",
                                  "psrl_continuous", "ucrl2"])
def test_tabular_agent_wrong_rank_dtype(name, mdp):
    agent = agents.get(name)
    m = jaxmdp.make("RiverSwim", size=4, episodic=True, seed=0).strip() if agent.episodic else mdp
    state = agent.init(jax.random.key(0), spec_of(m, 100), agent.default_hparams)
    key = jax.random.key(1)
    _raises(agent.update, state, _tr(obs=jnp.array([0, 1])), match=r"transition\.obs")
    _raises(agent.update, state, _tr(reward=jnp.int32(1)), match=r"reward floating")
    _raises(agent.update, state, _tr(next_obs=jnp.float32(1.0)), match=r"obs and next_obs state indices")
    _raises(agent.update, state, _tr(h=jnp.zeros(2, jnp.int32)), match=r"transition\.h")
    _raises(agent.act, key, state, jnp.array([0, 1]), jnp.int32(0), match=r"obs: one observation")
    _raises(agent.act, key, state, jnp.int32(0), jnp.float32(0.0), match=r"h: the in-episode step")
    # The correct step passes and compiles to the same program without the assertions.
    agent.update(state, _tr())
    _same_program_without_asserts(agent.update, state, _tr())
    _same_program_without_asserts(agent.act, key, state, jnp.int32(0), jnp.int32(0))


@pytest.mark.parametrize("name", ["dqn_continuous", "actor_critic_episodic"])
def test_deep_agent_wrong_shape(name, mdp):
    agent = agents.get(name)
    m = jaxmdp.make("RiverSwim", size=4, episodic=agent.episodic, seed=0).strip()
    block = jaxmdp.block_mdp(m, "one_hot")
    state = agent.init(jax.random.key(0), spec_of(block, 100), agent.default_hparams)
    obs = jnp.zeros(block.emissions.shape[-1], jnp.float32)
    wrong = jnp.zeros(obs.shape[0] + 1, jnp.float32)
    key = jax.random.key(1)
    _raises(agent.update, state, _tr(obs=wrong, next_obs=wrong), match=r"transition\.obs: one observation")
    _raises(agent.update, state, _tr(obs=obs, next_obs=obs, action=jnp.float32(1.0)), match=r"action and h integer")
    _raises(agent.act, key, state, wrong, jnp.int32(0), match=r"obs: one observation")
    _same_program_without_asserts(agent.update, state, _tr(obs=obs, next_obs=obs))
    _same_program_without_asserts(agent.act, key, state, obs, jnp.int32(0))
