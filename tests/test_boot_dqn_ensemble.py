"""BootDQN's ensemble as one computation (agents/deep/networks.py ``ensemble_apply``, agents/deep/boot_dqn.py): the
batched layers against every head's own MLP, the priors' outputs stored with each transition against the prior
networks, each head's gradient against its own masked loss computed head by head, and several SGD steps against the
earlier form of the loss (a ``vmap`` of the flax network over heads and batch, priors evaluated on the batch)."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from agents.deep import boot_dqn, dqn, replay
from agents.deep.networks import MLP, ensemble_apply
from tests.test_boot_dqn import SMALL, _fill, head
from tests.test_dqn import make_spec, np_q

DEEP = SMALL.replace(network_width=4, network_depth=2, discount=0.9, noise_scale=0.1, mask_prob=0.5)


def random_params(tree, seed):
    """Every leaf redrawn from N(0, 1) (MLP.init leaves the biases at zero, which would hide a missing bias)."""
    rng = np.random.default_rng(seed)
    return jax.tree.map(lambda x: jnp.asarray(rng.normal(size=x.shape), jnp.float32), tree)


@functools.partial(jax.jit, static_argnums=0)
def each_head(net, params, x):
    """``[K, B, out]``: head ``k``'s own flax network on every row of ``x``, one head at a time."""
    K = jax.tree.leaves(params)[0].shape[0]
    return jnp.stack([jax.vmap(lambda o: net.apply(head(params, k), o))(x) for k in range(K)])


def test_ensemble_apply_is_every_heads_mlp_on_every_row():
    x = jnp.asarray(np.random.default_rng(0).normal(size=(5, 2, 3)), jnp.float32)  # [B, *obs], flattened to 6
    # Dense_10 follows Dense_9 (10 hidden layers): layers are taken in numeric, not lexicographic, order.
    for K, hidden in [(3, (4,)), (3, (4, 3, 5)), (2, (3,) * 10)]:
        net = MLP(hidden=hidden, n_outputs=2)
        params = jax.vmap(lambda k: net.init(k, x[0]))(jax.random.split(jax.random.key(1), K))
        params = random_params(params, len(hidden))
        got = np.asarray(jax.jit(ensemble_apply)(params, x))
        assert got.shape == (K, 5, 2)
        np.testing.assert_allclose(got, np.asarray(each_head(net, params, x)), rtol=1e-4, atol=1e-4)


def test_the_acting_head_and_the_ensemble_agree():
    state = boot_dqn.init(jax.random.key(0), make_spec(), DEEP)
    state = state.replace(params=random_params(state.params, 1), prior_params=random_params(state.prior_params, 2))
    obs = jnp.array([0.3, -1.2])
    q = np.asarray(jax.jit(boot_dqn.ensemble_q)(state, state.params, obs))
    each = jax.jit(jax.vmap(boot_dqn.head_q, (None, 0, None)))(state, jnp.arange(3), obs)
    np.testing.assert_allclose(q, np.asarray(each), rtol=1e-5, atol=1e-5)


def filled(hp=DEEP, n=16):
    state = boot_dqn.init(jax.random.key(0), make_spec(), hp)
    state = state.replace(prior_params=random_params(state.prior_params, 3))
    return _fill(state, jnp.arange(n))[0]


def test_stored_prior_outputs_are_the_prior_networks_on_both_observations():
    hp = SMALL  # depth 1: np_q (float64, by hand) evaluates it
    state = filled(hp, 6)
    exp = state.replay.experience
    obs, next_obs = np.asarray(exp.obs[0, :6]), np.asarray(exp.next_obs[0, :6])
    assert not np.array_equal(obs, next_obs)
    for k in range(3):
        phi = head(state.prior_params, k)
        np.testing.assert_allclose(np.asarray(exp.prior_q[0, :6, k]), np_q(phi, obs), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(np.asarray(exp.next_prior_q[0, :6, k]), np_q(phi, next_obs), rtol=1e-5, atol=1e-6)


def sample(state, key):
    return replay.make(DEEP.replay_capacity, DEEP.batch_size).sample(state.replay, key).experience


def head_loss(theta, theta_target, phi, batch, k, state):
    """Head ``k``'s own loss ``1/2 mean_i m_ik delta_ik^2``, with the flax network of that head alone."""
    hp = state.hparams
    net = dqn.q_network(hp, state.n_actions)
    q = lambda p, o: jax.vmap(lambda x: net.apply(p, x) + hp.prior_scale * net.apply(phi, x))(o)  # noqa: E731
    delta = dqn.td_errors(q(theta, batch.obs), batch.action, batch.reward + hp.noise_scale * batch.noise[:, k],
                          hp.discount * batch.continuation, q(theta_target, batch.next_obs), state.action_mask)
    return 0.5 * jnp.mean(batch.mask[:, k] * delta**2)


def test_each_heads_gradient_is_that_of_its_own_masked_loss():
    state = filled()
    state = state.replace(params=random_params(state.params, 4), target_params=random_params(state.params, 5))
    batch = sample(state, jax.random.key(6))
    assert 0 < float(batch.mask.mean()) < 1 and float(jnp.abs(batch.noise).sum()) > 0
    loss, grads = jax.jit(jax.value_and_grad(boot_dqn.loss))(state.params, state.target_params, batch, state)
    losses = []
    own = jax.jit(jax.value_and_grad(head_loss))
    for k in range(3):
        args = (head(state.target_params, k), head(state.prior_params, k), batch, jnp.int32(k), state)
        lk, gk = own(head(state.params, k), *args)
        losses.append(float(lk))
        for got, want in zip(jax.tree.leaves(head(grads, k)), jax.tree.leaves(gk)):
            np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(float(loss), sum(losses), rtol=1e-5)


def vmapped_heads_loss(params, target_params, batch, state):
    """The loss as it was computed before the ensemble's batched layers: ``vmap`` of the flax network over heads
    (with the priors evaluated on the batch) and over the batch."""
    hp = state.hparams
    net = dqn.q_network(hp, state.n_actions)

    def ensemble(p, o):
        return jax.vmap(lambda t, phi: net.apply(t, o) + hp.prior_scale * net.apply(phi, o))(p, state.prior_params)

    q_tm1 = jax.vmap(lambda o: ensemble(params, o), out_axes=1)(batch.obs)
    q_t = jax.vmap(lambda o: ensemble(target_params, o), out_axes=1)(batch.next_obs)
    delta = jax.vmap(dqn.td_errors, (0, None, 0, None, 0, None))(
        q_tm1, batch.action, batch.reward + hp.noise_scale * batch.noise.T, hp.discount * batch.continuation, q_t,
        state.action_mask)
    return 0.5 * jnp.sum(jnp.mean(batch.mask.T * delta**2, axis=1))


@jax.jit
def _steps(state, keys):
    return jax.lax.scan(lambda s, k: (boot_dqn.sgd_step(k, s), None), state, keys)[0]


@jax.jit
def _vmapped_steps(state, keys):
    step = dqn.make_sgd_step(vmapped_heads_loss)
    return jax.lax.scan(lambda s, k: (step(k, s), None), state, keys)[0]


def test_sgd_steps_equal_those_of_the_vmapped_heads_loss():
    state = filled()
    keys = jax.random.split(jax.random.key(7), 6)  # 6 SGD steps: the target is copied after the 4th
    new, old = _steps(state, keys), _vmapped_steps(state, keys)
    assert int(new.sgd_steps) == 6
    for a, b in zip(jax.tree.leaves((new.params, new.target_params, new.opt_state)),
                    jax.tree.leaves((old.params, old.target_params, old.opt_state))):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-6)
    moved = jax.tree.leaves(jax.tree.map(lambda a, b: np.abs(np.asarray(a) - np.asarray(b)).max(),
                                         new.params, state.params))
    assert min(moved) > 1e-4  # the steps did move every leaf


def test_sgd_reads_the_stored_prior_outputs_not_the_prior_networks():
    state = filled()
    keys = jax.random.split(jax.random.key(8), 3)
    nan = state.replace(prior_params=jax.tree.map(lambda x: jnp.full_like(x, jnp.nan), state.prior_params))
    for a, b in zip(jax.tree.leaves(_steps(state, keys).params), jax.tree.leaves(_steps(nan, keys).params)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
