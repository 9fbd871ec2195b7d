"""The feed-forward actor-critic agents (agents.deep.actor_critic) and the policy-gradient pieces they share with the
recurrent ones (agents.deep.policy_gradient).

Formulas are checked against independent computations: the lambda-returns against the forward-view definition (a
lambda-weighted average of n-step returns, brute force in numpy) and the closed forms at lambda = 0 and 1; the
loss gradients against their closed forms in the logits and values. Learning is checked on probe MDPs with known
answers (tests/actor_critic_probes.py).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import actor_critic_probes as probes
import agents
from agents.deep import actor_critic as ac
from agents.deep import policy_gradient as pg
from agents.search_spaces import CHOICE_SPACES, sample_candidate_groups
from jaxmdp.experiment.agent_interface import Transition
from conftest import compilations
from stat_checks import Checks, failure_rate_bound, key

AC_NAMES = ("actor_critic_episodic", "actor_critic_continuous")
ALL_NAMES = AC_NAMES + ("actor_critic_rnn_episodic", "actor_critic_rnn_continuous")


# ---------------------------------------------------------------------------------------------------------------
# lambda-returns
# ---------------------------------------------------------------------------------------------------------------


def forward_view_returns(r, d, v, lam, n):
    """``G_t^lambda = (1 - lambda) sum_{k=1}^{m-1} lambda^{k-1} G_t^(k) + lambda^{m-1} G_t^(m)``, ``m = n - t``, with
    the k-step returns ``G_t^(k) = sum_{j<k} (prod_{i<j} d_{t+i}) r_{t+j} + (prod_{i<k} d_{t+i}) V_{t+k}``."""

    def k_step(t, k):
        total, disc = 0.0, 1.0
        for j in range(k):
            total += disc * r[t + j]
            disc *= d[t + j]
        return total + disc * v[t + k]

    out = []
    for t in range(n):
        m = n - t
        g = sum((1 - lam) * lam ** (k - 1) * k_step(t, k) for k in range(1, m)) + lam ** (m - 1) * k_step(t, m)
        out.append(g)
    return np.asarray(out)


@pytest.mark.parametrize("lam", [0.0, 0.3, 0.9, 1.0])
@pytest.mark.parametrize("n", [1, 4, 7])
def test_lambda_returns_match_the_forward_view(lam, n):
    rng = np.random.default_rng(int(10 * lam) + n)
    L = 7
    r = rng.normal(size=L)
    d = 0.9 * np.ones(L)
    d[2] = 0.0  # a terminal in the middle
    v = rng.normal(size=L + 1)
    G = np.asarray(pg.lambda_returns(jnp.asarray(r), jnp.asarray(d), jnp.asarray(v), lam, n))
    np.testing.assert_allclose(G[:n], forward_view_returns(r, d, v, lam, n), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(G[n:], v[n:L], rtol=1e-6)  # past the valid steps: the values themselves


def test_lambda_returns_closed_forms_and_a_hand_worked_example():
    r = jnp.asarray([1.0, 2.0, 3.0])
    d = jnp.asarray([0.5, 0.0, 0.5])  # the episode ends after step 1
    v = jnp.asarray([10.0, 20.0, 30.0, 40.0])
    # lambda = 0: one-step targets r_t + d_t V_{t+1}
    np.testing.assert_allclose(pg.lambda_returns(r, d, v, 0.0), [1 + 0.5 * 20, 2 + 0, 3 + 0.5 * 40])
    # lambda = 1: discounted returns to the end of the episode, or to the bootstrap value
    np.testing.assert_allclose(pg.lambda_returns(r, d, v, 1.0), [1 + 0.5 * 2, 2, 3 + 0.5 * 40])
    # lambda = 1/2 by hand: G_2 = 3 + 0.5 * 40 = 23; G_1 = 2; G_0 = 1 + 0.5 (0.5 * 20 + 0.5 * 2) = 6.5
    np.testing.assert_allclose(pg.lambda_returns(r, d, v, 0.5), [6.5, 2.0, 23.0])
    # two valid steps of three: G_1 bootstraps from V_2 = 30 (discount 0 there, so G_1 = r_1), G_0 as above
    np.testing.assert_allclose(pg.lambda_returns(r, d, v, 0.5, 2), [6.5, 2.0, 30.0])
    d2 = jnp.asarray([0.5, 0.5, 0.5])
    np.testing.assert_allclose(pg.lambda_returns(r, d2, v, 1.0, 2), [1 + 0.5 * (2 + 0.5 * 30), 2 + 0.5 * 30, 30.0])


# ---------------------------------------------------------------------------------------------------------------
# the loss and its gradients
# ---------------------------------------------------------------------------------------------------------------


def _buffer(rewards, discounts, actions, count, obs_dim=1):
    L = len(rewards)
    return pg.Trajectory(
        observations=jnp.zeros((L + 1, obs_dim)),
        actions=jnp.asarray(actions, jnp.int32),
        rewards=jnp.asarray(rewards, jnp.float32),
        discounts=jnp.asarray(discounts, jnp.float32),
        count=jnp.asarray(count, jnp.int32),
        due=jnp.asarray(True),
    )


@pytest.mark.parametrize("entropy_cost", [0.0, 0.3])
def test_loss_gradients_have_their_closed_forms(entropy_cost):
    rng = np.random.default_rng(0)
    L, n, A, gamma, lam = 5, 3, 3, 0.9, 0.7
    buf = _buffer(rng.normal(size=L), [1, 0, 1, 1, 1], rng.integers(0, A, size=L), n)
    logits = jnp.asarray(rng.normal(size=(L + 1, A)), jnp.float32)
    values = jnp.asarray(rng.normal(size=L + 1), jnp.float32)
    mask = jnp.ones(A, bool)

    def loss(z, v):
        return pg.actor_critic_loss(z, v, buf, mask, lam, gamma, entropy_cost)[0]

    gz, gv = jax.grad(loss, argnums=(0, 1))(logits, values)
    G = forward_view_returns(np.asarray(buf.rewards), gamma * np.asarray(buf.discounts), np.asarray(values), lam, n)
    adv = G - np.asarray(values[:n])
    # d/dV_t = -(G_t - V_t) / n on valid steps (returns are targets); nothing past them, nothing to the bootstrap
    np.testing.assert_allclose(gv[:n], -adv / n, rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(gv[n:], 0.0)
    # d/dz_ta = -(1[a = a_t] - pi_ta) adv_t / n + c pi_ta (log pi_ta + H_t) / n
    pi = np.asarray(jax.nn.softmax(logits[:n]))
    onehot = np.eye(A)[np.asarray(buf.actions[:n])]
    entropy = -(pi * np.log(pi)).sum(-1, keepdims=True)
    want = -(onehot - pi) * adv[:, None] / n + entropy_cost * pi * (np.log(pi) + entropy) / n
    np.testing.assert_allclose(gz[:n], want, rtol=1e-4, atol=1e-6)
    np.testing.assert_array_equal(gz[n:], 0.0)


def test_gradient_sign_on_a_one_step_example():
    """One step, reward 1 after which the episode ends, V = 0: the advantage is +1, so a gradient step raises the
    taken action's probability and the value; with reward -1 both go the other way."""
    mask = jnp.ones(2, bool)
    z0, v0 = jnp.zeros((2, 2)), jnp.zeros(2)
    for reward, sign in ((1.0, 1.0), (-1.0, -1.0)):
        buf = _buffer([reward], [0.0], [1], 1)
        gz, gv = jax.grad(lambda z, v: pg.actor_critic_loss(z, v, buf, mask, 0.9, 0.99, 0.0)[0], (0, 1))(z0, v0)
        z1, v1 = z0 - 0.1 * gz, v0 - 0.1 * gv
        assert sign * (jax.nn.softmax(z1[0])[1] - 0.5) > 0.01
        assert sign * v1[0] > 0.05


def test_padded_actions_leave_the_loss_finite():
    mask = jnp.asarray([True, True, False])
    buf = _buffer([1.0, 0.5], [1.0, 1.0], [0, 1], 2)
    logits, values = jnp.ones((3, 3)), jnp.zeros(3)
    loss, parts = pg.actor_critic_loss(logits, values, buf, mask, 0.9, 0.9, 0.5)
    gz = jax.grad(lambda z: pg.actor_critic_loss(z, values, buf, mask, 0.9, 0.9, 0.5)[0])(logits)
    assert np.isfinite(float(loss)) and np.all(np.isfinite(np.asarray(gz)))
    np.testing.assert_array_equal(gz[:, 2], 0.0)
    np.testing.assert_allclose(parts["entropy"], np.log(2.0), rtol=1e-6)  # uniform over the two valid actions


def test_argmax_policy_marks_ties_and_skips_padding():
    z = jnp.asarray([[1.0, 3.0, 3.0, 9.0], [2.0, 0.0, 1.0, 9.0], [-jnp.inf, -jnp.inf, -jnp.inf, 0.0]])
    mask = jnp.asarray([True, True, True, False])
    want = [[0, 0.5, 0.5, 0], [1, 0, 0, 0], [1 / 3, 1 / 3, 1 / 3, 0]]  # an all -inf row: uniform over valid ones
    np.testing.assert_allclose(pg.argmax_policy(z, mask), want, rtol=1e-7)


@pytest.mark.statistical(p=1e-7)
def test_sampling_follows_the_softmax_and_never_a_padded_action():
    # 20000 draws of pi = softmax(0, log 3, 9 [padded]) = (1/4, 3/4, 0): the count of action 1 is Binomial(n, 3/4)
    # exactly. 1 check (tests/stat_checks.py): false-failure probability <= 1e-7.
    n = 20000
    logits = jnp.asarray([0.0, np.log(3.0), 9.0])
    mask = jnp.asarray([True, True, False])
    a = jax.vmap(lambda k: pg.sample_action(k, logits, mask))(jax.random.split(key(0), n))
    assert set(np.unique(np.asarray(a))) <= {0, 1}
    Checks().binomial(int(jnp.sum(a == 1)), n, 0.75, "action 1, probability 3/4")
    nan = pg.sample_action(jax.random.key(1), jnp.full(3, jnp.nan), mask)
    assert int(nan) == 0


# ---------------------------------------------------------------------------------------------------------------
# the agent: init, validation, timing of the learning steps
# ---------------------------------------------------------------------------------------------------------------


def test_registered_with_defaults_and_search_space():
    for name in ALL_NAMES:
        agent = agents.get(name)
        assert agent.observation == "emission" and agent.episodic == name.endswith("episodic")
        hp = agent.default_hparams
        assert (hp.width, hp.depth, hp.max_sequence_length) == (64, 2, 32)
        assert (hp.learning_rate, hp.td_lambda, hp.discount, hp.entropy_cost) == (3e-3, 0.9, 0.99, 0.0)
        assert CHOICE_SPACES[name] == {
            "width": (64, 128, 256), "depth": (2, 4), "max_sequence_length": (16, 32, 64, 128),
            "td_lambda": (0.7, 0.8, 0.9),
        }
        groups = sample_candidate_groups(agent, jax.random.key(0), 5)
        assert sorted(i for index, _ in groups for i in index) == list(range(5))
        for index, c in groups:  # one grid per static configuration, td_lambda traced within it
            assert c.td_lambda.shape == (len(index),) and c.learning_rate.shape == (len(index),)
            assert set(np.asarray(c.td_lambda).tolist()) <= {0.7, 0.8, 0.9}
    assert agents.get("actor_critic_rnn_episodic").default_hparams.max_grad_norm == 5.0


def test_init_needs_an_emission_table_of_the_right_setting():
    agent = agents.get("actor_critic_episodic")
    with pytest.raises(ValueError, match=r"jaxmdp.block_mdp\(mdp, 'state_info'\)"):
        agent.init(jax.random.key(0), probes.spec(True, table=False), agent.default_hparams)
    with pytest.raises(ValueError, match="episodic"):
        agent.init(jax.random.key(0), probes.spec(False), agent.default_hparams)
    spec = probes.spec(True)
    with pytest.raises(ValueError, match=r"\[H, S, \*obs\]"):
        agent.init(jax.random.key(0), spec.replace(observations=spec.observations[0]), agent.default_hparams)


BAD_HPARAMS = [
    ("learning_rate", 0.0),
    ("learning_rate", float("nan")),
    ("td_lambda", 1.5),
    ("discount", -0.1),
    ("entropy_cost", -1.0),
    ("width", 0),
    ("depth", 1.5),
    ("max_sequence_length", True),
]


@pytest.mark.parametrize(("field", "value"), BAD_HPARAMS)
def test_bad_hyperparameters_are_rejected(field, value):
    for name in ALL_NAMES:
        agent = agents.get(name)
        with pytest.raises(ValueError, match=field):
            agent.check_hparams(agent.default_hparams.replace(**{field: value}))
    agent.check_hparams(agent.default_hparams.replace(learning_rate=np.asarray([1e-3, 1e-2])))  # a grid is fine


@pytest.mark.parametrize("name", AC_NAMES)
def test_learning_steps_happen_exactly_at_buffer_full_or_episode_end(name):
    agent = agents.get(name)
    hp = agent.default_hparams.replace(width=8, depth=1, max_sequence_length=3)
    learned, _, states = probes.stream(agent, hp, terminals={1, 6}, n=12)
    # L = 3, episode ends after steps 1 and 6: episodic learns after 1 (end), 4 (full), 6 (end), 9 (full); the
    # continuous agent never sees an episode end: every third step.
    assert learned == ([1, 4, 6, 9] if agent.episodic else [2, 5, 8, 11])
    after = [plan_state for _, plan_state in states[1:]]
    assert [int(s.n_updates) for s in after] == [sum(t <= u for t in learned) for u in range(12)]
    for t in range(12):  # the parameters change exactly at the learning steps; the buffer restarts there
        before = states[0] if t == 0 else after[t - 1]
        pairs = zip(jax.tree.leaves(before.params), jax.tree.leaves(after[t].params), strict=True)
        changed = any(not np.array_equal(a, b) for a, b in pairs)
        assert changed == (t in learned)
        assert int(after[t].buffer.count) == (0 if t in learned else int(before.buffer.count) + 1)


def test_episodic_buffer_holds_at_most_an_episode():
    # probes.spec: episodes of H = 2 steps; the default sequence length is 32
    for name, length in zip(ALL_NAMES, (2, 32, 2, 32), strict=True):
        agent = agents.get(name)
        state = agent.init(jax.random.key(0), probes.spec(agent.episodic), agent.default_hparams.replace(width=4))
        assert state.buffer.max_length == length and state.buffer.observations.shape == (length + 1, 3)


def test_plan_is_a_no_op_when_no_learning_step_is_due():
    agent = agents.get("actor_critic_continuous")
    state = agent.init(jax.random.key(0), probes.spec(False), agent.default_hparams.replace(width=8, depth=1))
    again = agent.plan(jax.random.key(1), state)
    for a, b in zip(jax.tree.leaves(state), jax.tree.leaves(again), strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_learning_step_moves_value_and_policy_towards_the_return():
    """A one-step episode with reward +1 (resp. -1): after one learning step V(o) and pi(a|o) go up (resp. down);
    the other observation's outputs barely move."""
    agent = agents.get("actor_critic_episodic")
    hp = agent.default_hparams.replace(width=8, depth=1, learning_rate=1e-2)
    spec = probes.spec(True)
    state = agent.init(jax.random.key(0), spec, hp)
    o = spec.observations[0, 0]
    for reward, sign in ((1.0, 1.0), (-1.0, -1.0)):
        tr = Transition(o, jnp.asarray(1), jnp.asarray(reward), o, jnp.asarray(1), jnp.asarray(True))
        s1 = agent.plan(jax.random.key(0), agent.update(state, tr))
        (z0, v0), (z1, v1) = (state.net.apply(s.params, o) for s in (state, s1))
        assert sign * (float(v1) - float(v0)) > 0
        assert sign * (float(jax.nn.softmax(z1)[1]) - float(jax.nn.softmax(z0)[1])) > 0


def _first_adam_moves(field: str, value: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 4-step sequence learned once with ``field = value``: the parameters' moves, the gradient of
    :func:`pg.actor_critic_loss` (tested against closed forms above) at the state's hyperparameters, and at the
    defaults, each flattened."""
    agent = agents.get("actor_critic_continuous")
    hp = agent.default_hparams.replace(width=8, depth=1, learning_rate=1e-2, max_sequence_length=4, **{field: value})
    learned, _, states = probes.stream(agent, hp, terminals=set(), n=4)
    before, after = states[learned[0] + 1]

    def grad(h):
        def loss(p):
            logits, values = jax.vmap(lambda o: before.net.apply(p, o))(before.buffer.observations)
            return pg.actor_critic_loss(logits, values, before.buffer, before.action_mask, h.td_lambda, h.discount,
                                        h.entropy_cost)[0]

        return np.concatenate([np.ravel(g) for g in jax.tree.leaves(jax.grad(loss)(before.params))])

    flat = lambda t: np.concatenate([np.ravel(x) for x in jax.tree.leaves(t)])  # noqa: E731
    default = jax.tree.map(jnp.float32, agent.default_hparams)
    return flat(after.params) - flat(before.params), grad(before.hparams), grad(default)


@pytest.mark.parametrize("field, value", [("td_lambda", 0.2), ("discount", 0.3), ("entropy_cost", 0.8)])
def test_a_learning_step_uses_the_state_s_td_lambda_discount_and_entropy_cost(field, value):
    """Adam's first step moves each parameter by ``-lr * g / (|g| + 1e-8)``, ``g`` the loss gradient at the state's
    own hyperparameters; at the defaults some gradient has the other sign, so a learning step that dropped ``field``
    would fail here."""
    moved, g, g_default = _first_adam_moves(field, value)
    big = np.abs(g) > 1e-4
    np.testing.assert_allclose(moved[big], -1e-2 * np.sign(g[big]), atol=1e-6)
    assert np.all(np.abs(moved) <= 1e-2 + 1e-6)
    assert np.any(np.sign(g_default[big]) != np.sign(g[big]))


@pytest.mark.parametrize("name", AC_NAMES)
def test_policy_estimate_is_read_from_the_emission_table(name):
    agent = agents.get(name)
    spec = probes.spec(agent.episodic)
    state = agent.init(jax.random.key(0), spec, agent.default_hparams.replace(width=8, depth=1))
    pi = agent.policy(state)
    lead = (probes.H, 2) if agent.episodic else (2,)
    assert pi.shape == (*lead, probes.PADDED_A)
    rows = spec.observations.reshape(-1, 3)
    z = jax.vmap(lambda o: state.net.apply(state.params, o)[0])(rows)[:, : probes.A]
    greedy = np.eye(probes.A)[np.argmax(z, -1)]
    np.testing.assert_array_equal(np.asarray(pi).reshape(-1, probes.PADDED_A)[:, : probes.A], greedy)
    np.testing.assert_array_equal(pi[..., probes.A], 0.0)


# ---------------------------------------------------------------------------------------------------------------
# learning on probes (one compiled run per agent; vmapped over a learning-rate grid and seeds)
# ---------------------------------------------------------------------------------------------------------------

probe_run = probes.probe_run_fixture(AC_NAMES)


class TestProbeLearning(probes.ProbeLearning):
    """Bandit, constant reward, discounting chain (values on the emission table), members of the learning-rate
    grid independent, same key same result."""

    atol = 0.02
    # Measured per-member failures of `passes` on 1024 independent members per agent and probe (512 seeds x 2 learning
    # rates from 10**6, every member its own key; `PYTHONPATH=$PWD python tests/probe_failure_rates.py actor_critic
    # --only actor_critic_e --seeds 512 --chunk 256`, likewise `actor_critic_c`). The bandit's errors are heavy-tailed
    # (median 0.002 tolerances, 99% quantile 1.6-1.9, worst 5-16). q_u: Clopper-Pearson bounds at miss
    # probability 1e-3 (tests/stat_checks.py); stat_checks.allowed_failures(16, q_u) of the 16 members may fail: 4 for
    # the constant and chain probes, 7 and 8 for the bandit.
    measured = {(name, kind): 0 for name in AC_NAMES for kind in ("constant", "chain")} | {
        ("actor_critic_episodic", "bandit"): 17, ("actor_critic_continuous", "bandit"): 27}
    q_learn = {pair: failure_rate_bound(failures, 1024) for pair, failures in measured.items()}

    @staticmethod
    def outputs(state, kind, episodic):
        del kind, episodic
        return probes.evaluate_grid(ac.evaluate, state)


def test_lambda_returns_compile_once_per_shape(caplog):
    # Jitted: a second eager call with other numbers (and another valid length) compiles nothing.
    full = lambda n, x: jnp.asarray(np.full(n, x, np.float32))  # noqa: E731  (not weakly typed, as jnp.full)
    r, d, v, r2, v2 = full(5, 1.0), full(5, 0.9), full(6, 0.0), full(5, 2.0), full(6, 1.0)
    assert compilations(caplog, [lambda: pg.lambda_returns(r, d, v, 0.5, 3)])
    assert compilations(caplog, [lambda: pg.lambda_returns(r2, d, v2, 0.7, 4)]) == []
