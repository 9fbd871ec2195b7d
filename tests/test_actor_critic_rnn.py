"""The recurrent actor-critic agents (agents.deep.actor_critic_rnn): the LSTM state (advanced in ``update``, reset
at episode start, replayed from the sequence start in the learning step), the gradient clip, the policy estimate
from a fresh state, and learning on the probe MDPs of tests/actor_critic_probes.py (the shared policy-gradient
pieces are tested in test_actor_critic.py)."""

from __future__ import annotations

import re

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

import actor_critic_probes as probes
from stat_checks import failure_rate_bound
import agents
from agents.deep import actor_critic_rnn as acr
from agents.deep import policy_gradient as pg
from agents.deep.common import cast_hparams, make_optimizer
from agents.deep.networks import orthogonal

RNN_NAMES = ("actor_critic_rnn_episodic", "actor_critic_rnn_continuous")


def _small(agent, **kw):
    return agent.default_hparams.replace(width=8, depth=1, **kw)


def _leaves_close(a, b) -> bool:
    """Equal up to float rounding (a jitted update and an eager apply may fuse operations differently)."""
    pairs = zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True)
    return all(np.allclose(x, y, rtol=1e-5, atol=1e-6) for x, y in pairs)


TERMINALS = {2, 5}


@pytest.fixture(scope="module", params=RNN_NAMES)
def scripted(request):
    """A scripted stream of 11 steps (episode ends after steps 2 and 5; sequences of 4) and a jitted network step."""
    agent = agents.get(request.param)
    learned, transitions, states = probes.stream(agent, _small(agent, max_sequence_length=4), TERMINALS, 11)
    return agent, learned, transitions, states, jax.jit(states[0].net.apply)


def test_lstm_state_advances_in_update_and_resets_at_episode_start(scripted):
    agent, learned, transitions, states, apply = scripted
    for t, tr in enumerate(transitions):
        before = states[0] if t == 0 else states[t][1]
        updated = states[t + 1][0]
        stepped, _ = apply(before.params, before.carry, tr.obs)  # what act used, one step on
        if agent.episodic and t in TERMINALS:
            assert all(np.all(np.asarray(c) == 0) for c in updated.carry)
        else:
            assert _leaves_close(updated.carry, stepped)
            assert all(np.any(np.asarray(c) != 0) for c in updated.carry)
    assert learned == ([2, 5, 9] if agent.episodic else [3, 7])


def test_learning_replays_the_sequence_from_its_start_state(scripted):
    """Before each learning step, the unroll from ``start_carry`` over the buffer reproduces the logits and values
    the agent acted with at every step of the sequence, and its bootstrap value is that of the next observation
    from the current acting state; after it, the next sequence starts from the acting state."""
    agent, learned, transitions, states, apply = scripted
    start = 0
    for t in learned:
        updated, planned = states[t + 1]
        n = int(updated.buffer.count)
        assert n == t + 1 - start
        _, (logits, values) = acr.unroll(updated.net, updated.params, updated.start_carry, updated.buffer.observations)
        for j in range(n):
            before = states[0] if start + j == 0 else states[start + j][1]
            _, (z, v) = apply(updated.params, before.carry, transitions[start + j].obs)
            np.testing.assert_allclose(logits[j], z, rtol=1e-5, atol=1e-6)
            np.testing.assert_allclose(values[j], v, rtol=1e-5, atol=1e-6)
        if not (agent.episodic and t in TERMINALS):  # after an episode end the bootstrap value is discounted away
            _, (_, v_next) = apply(updated.params, updated.carry, transitions[t].next_obs)
            np.testing.assert_allclose(values[n], v_next, rtol=1e-5, atol=1e-6)
        assert all(np.array_equal(x, y) for x, y in zip(planned.start_carry, updated.carry))
        start = t + 1


def test_gradients_flow_through_the_unrolled_sequence(scripted):
    agent, _, _, states, _ = scripted
    # 3 steps into a sequence: continuous, the second one (a non-zero start state); episodic, the third episode's
    state = states[9 if agent.episodic else 7][0]
    assert int(state.buffer.count) == 3
    if not agent.episodic:
        assert all(np.any(np.asarray(c) != 0) for c in state.start_carry)
    obs = state.buffer.observations
    # the last value depends on the first observation through the LSTM
    last_value = jax.jit(jax.grad(lambda o: acr.unroll(state.net, state.params, state.start_carry, o)[1][1][3]))
    assert np.all(np.abs(np.asarray(last_value(obs)[0])) > 0)

    def loss(params, start_carry):
        logits, values = acr.unroll(state.net, params, start_carry, obs)[1]
        hp = state.hparams
        return pg.actor_critic_loss(logits, values, state.buffer, state.action_mask, hp.td_lambda, hp.discount, 0.0)[0]

    g_params, g_carry = jax.jit(jax.grad(loss, argnums=(0, 1)))(state.params, state.start_carry)
    lstm = g_params["params"]["OptimizedLSTMCell_0"]
    assert all(np.any(np.asarray(x) != 0) for x in jax.tree.leaves(lstm))
    assert all(np.any(np.asarray(x) != 0) for x in g_carry)  # the stored start state enters the loss


def _stepwise(net, params, carry, observations):
    """The independent computation: flax's cell applied step by step in a scan, differentiated by JAX."""
    return jax.lax.scan(lambda c, o: net.apply(params, c, o), carry, observations)


def test_the_sequence_unroll_and_its_written_out_gradient_match_the_stepwise_cell():
    # acr.unroll runs only the recurrence step by step and back-propagates through time by hand (lstm_sequence's
    # custom VJP); the flax cell scanned and differentiated by JAX must give the same outputs, final state and
    # gradients (parameters and start state), for three members under vmap as the runner calls it. A sign or a gate
    # derivative wrong in the backward pass moves some gradient by far more than rounding.
    net = acr.PolicyValueRNN(width=16, depth=2, n_actions=3)
    keys = jax.random.split(jax.random.key(3), 4)
    obs = jax.random.normal(keys[0], (3, 9, 5))
    carry = (0.7 * jax.random.normal(keys[1], (3, 16)), 0.7 * jax.random.normal(keys[2], (3, 16)))
    params = jax.vmap(lambda k: net.init(k, acr.zero_carry(16), obs[0, 0]))(jax.random.split(keys[3], 3))
    weights = jax.random.normal(jax.random.key(4), (9, 3))

    def loss(unroll, p, c, o):
        (c_last, h_last), (logits, values) = unroll(net, p, c, o)
        return jnp.sum(jnp.sin(logits) * weights) + jnp.sum(values**2) + jnp.sum(c_last * h_last) + jnp.sum(h_last)

    outputs = {f: jax.jit(jax.vmap(lambda *a, f=f: f(net, *a)))(params, carry, obs) for f in (acr.unroll, _stepwise)}
    for ours, theirs in zip(*map(jax.tree.leaves, outputs.values()), strict=True):
        np.testing.assert_allclose(ours, theirs, rtol=1e-6, atol=1e-6)
    grads = {f: jax.jit(jax.vmap(jax.grad(lambda p, c, o, f=f: loss(f, p, c, o), argnums=(0, 1))))(params, carry, obs)
             for f in (acr.unroll, _stepwise)}
    lstm = grads[acr.unroll][0]["params"]["OptimizedLSTMCell_0"]
    assert all(np.all(np.abs(np.asarray(x)) > 0) for x in jax.tree.leaves(lstm["hf"]))  # the gates all learn
    for (path, ours), theirs in zip(jax.tree_util.tree_leaves_with_path(grads[acr.unroll]),
                                    jax.tree.leaves(grads[_stepwise]), strict=True):
        scale = float(np.max(np.abs(theirs)))
        np.testing.assert_allclose(ours, theirs, rtol=1e-5, atol=1e-6 * scale, err_msg=jax.tree_util.keystr(path))


def test_gradient_is_clipped_to_the_global_norm_before_adam():
    hp = cast_hparams(acr.ActorCriticRNNHParams(max_grad_norm=0.5))
    grads = {"a": jnp.asarray([3.0, 4.0]), "b": jnp.asarray([[12.0]])}  # global norm 13
    opt = make_optimizer(hp)
    _, opt_state = opt.update(grads, opt.init(grads))
    adam = [s for s in jax.tree.leaves(opt_state, is_leaf=lambda x: isinstance(x, optax.ScaleByAdamState))
            if isinstance(s, optax.ScaleByAdamState)][0]
    b1 = 0.9  # Adam's first moment after one step: (1 - b1) * (clipped gradient)
    np.testing.assert_allclose(adam.mu["a"], (1 - b1) * np.asarray([3.0, 4.0]) * 0.5 / 13, rtol=1e-6)
    np.testing.assert_allclose(adam.mu["b"], (1 - b1) * np.asarray([[12.0]]) * 0.5 / 13, rtol=1e-6)


def test_policy_estimate_uses_a_fresh_lstm_state(scripted):
    agent, _, _, states, _ = scripted
    state = states[4][1]
    zero = acr.zero_carry(state.net.width)
    moved = state.replace(carry=jax.tree.map(lambda c: c + 1.0, state.carry))
    np.testing.assert_array_equal(agent.policy(state), agent.policy(moved))
    rows = state.observations.reshape(-1, state.observations.shape[-1])
    z = jax.vmap(lambda o: state.net.apply(state.params, zero, o)[1][0])(rows)
    want = np.asarray(pg.argmax_policy(z, state.action_mask)).reshape(agent.policy(state).shape)
    np.testing.assert_array_equal(agent.policy(state), want)
    lead = (probes.STREAM_HORIZON, probes.S) if agent.episodic else (probes.S,)
    assert agent.policy(state).shape == (*lead, probes.PADDED_A)


@pytest.mark.parametrize("shape", [(8, 8), (5, 3), (3, 5), (2, 3, 4)])
def test_orthogonal_initialiser_is_jax_s_draw_for_draw(shape):
    """The recurrent kernels' initialiser is flax's default (``jax.nn.initializers.orthogonal``) bit for bit, alone
    and under vmap, and its matrices are orthonormal."""
    keys = jax.random.split(jax.random.key(3), 6)
    ours, ref = orthogonal(), jax.nn.initializers.orthogonal()
    one = jax.jit(lambda k: ours(k, shape, jnp.float32))(keys[0])
    np.testing.assert_array_equal(one, jax.jit(lambda k: ref(k, shape, jnp.float32))(keys[0]))
    batch = jax.jit(jax.vmap(lambda k: ours(k, shape, jnp.float32)))(keys)
    np.testing.assert_array_equal(batch, jax.jit(jax.vmap(lambda k: ref(k, shape, jnp.float32)))(keys))
    m = np.asarray(one, np.float64).reshape(-1, shape[-1])
    gram = m.T @ m if m.shape[0] >= m.shape[1] else m @ m.T
    np.testing.assert_allclose(gram, np.eye(min(m.shape)), atol=1e-6)


def test_init_of_a_grid_hands_lapack_one_matrix_per_call():
    """Initialising members under vmap (every grid) must not run a batched LAPACK QR: jaxlib 0.10.2 splits a batch
    over its CPU thread pool and the LSTM's four concurrent QRs deadlocked the learning probes (both pool workers in
    jax::QrFactorization -> jax::ParallelBatchMap -> BlockingCounter::Wait). One matrix per call runs inline."""
    agent = agents.get("actor_critic_rnn_continuous")
    spec, hp = probes.spec(False), _small(agent)
    init = jax.vmap(lambda k: agent.init(k, spec, hp).params)
    text = jax.jit(init).lower(jax.random.split(jax.random.key(0), 4)).as_text()
    operands = re.findall(r"stablehlo.custom_call @(lapack_\w+)\(%[^)]*\).*?: \((tensor<[^>]*>)", text)
    assert {t for t, _ in operands} == {"lapack_sgeqrf_ffi", "lapack_sorgqr_ffi"}
    assert {x for _, x in operands} == {"tensor<8x8xf32>"}


@pytest.mark.parametrize("value", [0.0, -1.0, float("inf")])
def test_bad_clip_norm_is_rejected(value):
    """(The other hyperparameters' checks, shared with the feed-forward agents, are in test_actor_critic.py.)"""
    for name in RNN_NAMES:
        agent = agents.get(name)
        with pytest.raises(ValueError, match="max_grad_norm"):
            agent.check_hparams(agent.default_hparams.replace(max_grad_norm=value))


def test_init_needs_an_emission_table():
    agent = agents.get("actor_critic_rnn_continuous")
    with pytest.raises(ValueError, match=r"jaxmdp.block_mdp\(mdp, 'state_info'\)"):
        agent.init(jax.random.key(0), probes.spec(False, table=False), agent.default_hparams)


# ---------------------------------------------------------------------------------------------------------------
# learning on probes (one compiled run per agent; vmapped over a learning-rate grid and seeds)
# ---------------------------------------------------------------------------------------------------------------

probe_run = probes.probe_run_fixture(RNN_NAMES)


def on_policy_outputs(state, kind: str, episodic: bool):
    """Logits and values along the states the agent visits next, ``[G, B, *lead, A]`` and ``[G, B, *lead]`` (NaN
    off the path): episodic, an episode from a fresh LSTM state; continuous, the next two steps from the acting
    state (every run has an even number of steps, so it is back in state 0)."""
    table = probes.emission_table(episodic)
    path = {"chain": [0, 1]}.get(kind, [0, 0])
    obs = jnp.stack([table[h, s] for h, s in enumerate(path)]) if episodic else table[jnp.asarray(path)]

    def one(st):
        carry = acr.zero_carry(st.net.width) if episodic else st.carry
        return acr.unroll(st.net, st.params, carry, obs)[1]

    logits, values = jax.vmap(jax.vmap(one))(state)
    lead = (probes.H, probes.S) if episodic else (probes.S,)
    G, B = values.shape[:2]
    z, v = np.full((G, B, *lead, probes.PADDED_A), np.nan), np.full((G, B, *lead), np.nan)
    for i, s in enumerate(path):
        index = (i, s) if episodic else (s,)
        z[(slice(None), slice(None), *index)] = logits[:, :, i]
        v[(slice(None), slice(None), *index)] = values[:, :, i]
    return z, v


class TestProbeLearning(probes.ProbeLearning):
    """Bandit, constant reward, discounting chain (values along the on-policy path), members of the learning-rate
    grid independent, same key same result."""

    atol = 0.05
    # Measured per-member failures of `passes` on 1024 independent members per agent and probe (512 seeds x 2 learning
    # rates from 10**6, every member its own key; `PYTHONPATH=$PWD python tests/probe_failure_rates.py actor_critic
    # --only actor_critic_rnn --seeds 512 --chunk 256`). q_u: Clopper-Pearson bounds at miss probability 1e-3
    # (tests/stat_checks.py); stat_checks.allowed_failures(16, q_u) of the 16 members may fail: 4 for 0 failures of
    # 1024, 6 and 7 for the bandit's 10 and 15.
    measured = {(name, kind): 0 for name in RNN_NAMES for kind in ("constant", "chain")} | {
        ("actor_critic_rnn_episodic", "bandit"): 10, ("actor_critic_rnn_continuous", "bandit"): 15}
    q_learn = {pair: failure_rate_bound(failures, 1024) for pair, failures in measured.items()}
    outputs = staticmethod(on_policy_outputs)
