"""Random and Q-learning agents: update rules against hand computation in numpy, action masks, registry, and probe
MDPs with known optimal policies (a one-state bandit and tiny chains) that each agent must solve within a budget."""

from __future__ import annotations

import math
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import agents
import jaxmdp
from agents import q_learning_continuous as qlc
from agents import q_learning_episodic as qle
from agents.tabular_common import (
    discounted_greedy_policy,
    greedy_action,
    greedy_action_single_draw,
    max_and_first_argmax,
    read_at,
    row_max,
    write_at,
)
from jaxmdp.experiment import runner
from jaxmdp.experiment.agent_interface import Transition, spec_of
from stat_checks import Checks, failure_rate_bound, key, mostly, seed


def tr(s, a, r, s2, h=0):
    return Transition(obs=jnp.int32(s), action=jnp.int32(a), reward=jnp.float32(r), next_obs=jnp.int32(s2),
                      h=jnp.int32(h), terminated=jnp.bool_(False))


# ---------------------------------------------------------------------------------------------------------------
# Q-learning, episodic (Jin et al. 2018)
# ---------------------------------------------------------------------------------------------------------------


def jin_reference(transitions, H, S, A, T, hp):
    """Algorithms 1 and 2 of Jin et al. written out in numpy, one transition at a time."""
    iota = math.log(S * A * T / hp["p"])
    Q = np.full((H, S, A), float(H))
    V = np.vstack([np.full((H, S), float(H)), np.zeros((1, S))])
    N = np.zeros((H, S, A))
    seen = {}
    beta_prev = np.zeros((H, S, A))
    for h, s, a, r, s2 in transitions:
        N[h, s, a] += 1
        t = N[h, s, a]
        alpha = max(hp["min_at"], (H + 1) / (H + t))
        seen.setdefault((h, s, a), []).append(V[h + 1, s2])
        if hp["bernstein"]:
            vals = np.array(seen[(h, s, a)])
            W = np.mean((vals - vals.mean()) ** 2)
            beta = min(hp["c_1"] * (math.sqrt(H / t * (W + H) * iota) + math.sqrt(H**7 * S * A) * iota / t),
                       hp["c_2"] * math.sqrt(H**3 * iota / t))
            b = (beta - (1 - alpha) * beta_prev[h, s, a]) / (2 * alpha)
            beta_prev[h, s, a] = beta
        else:
            b = hp["c_1"] * math.sqrt(H**3 * iota / t)
        Q[h, s, a] = (1 - alpha) * Q[h, s, a] + alpha * (r + V[h + 1, s2] + b)
        V[h, s] = min(H, Q[h, s].max())
    return Q, V, N


@pytest.mark.parametrize("bernstein", [True, False])
def test_jin_update_matches_numpy(bernstein):
    mdp = jaxmdp.custom_mdp(np.full((3, 2, 3), 1 / 3), R=np.zeros((3, 2)), H=3)
    hp = dict(c_1=0.3, c_2=0.8, min_at=0.05, p=0.05, bernstein=bernstein)
    state = qle.init(jax.random.key(0), spec_of(mdp, 1000), qle.QLearningEpisodicHParams(**hp))
    rng = np.random.default_rng(0)
    # Repeated visits to a few (h, s, a) with varying next states, so the variance term and beta history matter.
    transitions = [(int(rng.integers(0, 2)), int(rng.integers(0, 2)), 1, float(rng.random()), int(rng.integers(0, 3)))
                   for _ in range(40)]
    transitions = [(h + 1 if k % 3 == 0 else h, s, a, r, s2) for k, (h, s, a, r, s2) in enumerate(transitions)]
    update = jax.jit(qle.update)
    for h, s, a, r, s2 in transitions:
        state = update(state, tr(s, a, r, s2, h))
    Q, V, N = jin_reference(transitions, 3, 3, 2, 1000, hp)
    np.testing.assert_allclose(state.Q, Q, rtol=2e-5)
    np.testing.assert_allclose(state.V, V, rtol=2e-5)
    np.testing.assert_array_equal(state.N, N)


def test_jin_first_visit_overwrites_with_target():
    # alpha_1 = 1 (counts start at 0): the first update replaces the optimistic H by r + V_{h+1}(s') + b_1.
    mdp = jaxmdp.custom_mdp(np.full((2, 2, 2), 0.5), R=np.zeros((2, 2)), H=2)
    hp = qle.QLearningEpisodicHParams(bernstein=False, c_1=0.1, min_at=0.0)
    state = qle.init(jax.random.key(0), spec_of(mdp, 100), hp)
    state = qle.update(state, tr(0, 1, 0.3, 1, h=1))
    b1 = 0.1 * math.sqrt(2**3 * math.log(2 * 2 * 100 / 0.05))  # 0.849
    assert float(state.Q[1, 0, 1]) == pytest.approx(0.3 + 0.0 + b1, rel=1e-6)  # V_H = 0 at the last step
    assert float(state.V[1, 0]) == 2.0  # action 0 is still at its optimistic H = 2
    # Both actions visited: V = min(H, max_a Q) = max(0.3 + b1, 0.1 + b1) = 1.149 < H.
    state = qle.update(state, tr(0, 0, 0.1, 1, h=1))
    assert float(state.Q[1, 0, 0]) == pytest.approx(0.1 + b1, rel=1e-6)
    assert float(state.V[1, 0]) == pytest.approx(0.3 + b1, rel=1e-6)


# ---------------------------------------------------------------------------------------------------------------
# Optimistic Q-learning, continuous (Wei et al. 2020)
# ---------------------------------------------------------------------------------------------------------------


def wei_constants(hw, sp, delta, S, A, T, exponent=1 / 3):
    H = hw * min(math.sqrt(sp * T / (S * A)), (T / (S * A * math.log(4 * T / delta))) ** exponent)
    return H, 1 - 1 / H, 4 * sp * math.sqrt(H * math.log(2 * T / delta))


def test_wei_constants():
    # The spec's derived values (docs/agents.md §5: S=25, A=2, T=500 000 -> H = 8.2931, bonus at N=1 0.6005) come from
    # the reference's delta = 0.95 and exponent 0.333; they check this reading of the formulas.
    H, _, b = wei_constants(0.942, 0.014, 0.95, 25, 2, 500_000, exponent=0.333)
    assert H == pytest.approx(8.2931, abs=1e-4) and b == pytest.approx(0.6005, abs=1e-4)
    # The agent against the spec's derived table itself (cached hparams, delta = 0.95, T = 500 000): the agent's
    # exponent is 1/3 where the reference wrote 0.333, which moves H by a factor x^(1/3 - 0.333) < 1.004 (x < 1e4
    # the cube root's argument), so H within 0.4% and gamma = 1 - 1/H.
    hp = qlc.QLearningContinuousHParams(h_weight=0.942, span_approx_weight=0.014, delta=0.95)
    for (S, A), (H_ref, gamma_ref) in {(25, 2): (8.2931, 0.87942), (100, 5): (3.5246, 0.71628),
                                       (400, 3): (2.275, 0.5605), (820, 2): (1.946, 0.486)}.items():
        H, gamma, scale, _ = (float(x) for x in qlc.constants(hp, S, A, 500_000))
        assert H == pytest.approx(H_ref, rel=4e-3) and gamma == pytest.approx(1 - 1 / H, rel=1e-6), (S, A)
        assert gamma == pytest.approx(gamma_ref, abs=4e-3), (S, A)
        if (S, A) == (25, 2):
            assert scale == pytest.approx(0.6005, rel=4e-3)  # the bonus at N = 1
    for delta, S, A in [(0.05, 25, 2), (0.95, 100, 5), (0.05, 400, 3)]:
        hp = qlc.QLearningContinuousHParams(delta=delta)
        H, gamma, scale, min_at = qlc.constants(hp, S, A, 500_000)
        want = wei_constants(0.942, 0.014, delta, S, A, 500_000)
        np.testing.assert_allclose([H, gamma, scale], want, rtol=1e-5)
        assert float(min_at) == pytest.approx(0.073)
    assert float(qlc.constants(qlc.QLearningContinuousHParams(min_at=0.005), 5, 2, 1000)[3]) == 0.0
    assert float(qlc.constants(qlc.QLearningContinuousHParams(h_weight=1e-3), 5, 2, 1000)[0]) == 1.0  # floor


def test_wei_update_matches_numpy():
    mdp = jaxmdp.custom_mdp(np.full((3, 2, 3), 1 / 3), R=np.zeros((3, 2)))
    hp = qlc.QLearningContinuousHParams(h_weight=1.0, span_approx_weight=0.5, min_at=0.2)
    state = qlc.init(jax.random.key(0), spec_of(mdp, 2000), hp)
    H, gamma, scale = wei_constants(1.0, 0.5, 0.05, 3, 2, 2000)
    Q, Qh, V, N = np.full((3, 2), H), np.full((3, 2), H), np.full(3, H), np.zeros((3, 2))
    rng = np.random.default_rng(1)
    update = jax.jit(qlc.update)
    for _ in range(60):
        s, a, s2, r = int(rng.integers(0, 2)), int(rng.integers(0, 2)), int(rng.integers(0, 3)), float(rng.random())
        state = update(state, tr(s, a, r, s2))
        N[s, a] += 1
        alpha = max(0.2, (H + 1) / (H + N[s, a]))
        Q[s, a] = (1 - alpha) * Q[s, a] + alpha * (r + gamma * V[s2] + scale / math.sqrt(N[s, a]))
        Qh[s, a] = min(Qh[s, a], Q[s, a])
        V[s] = Qh[s].max()
    np.testing.assert_allclose(state.Q, Q, rtol=1e-5)
    np.testing.assert_allclose(state.Q_hat, Qh, rtol=1e-5)
    np.testing.assert_allclose(state.V, V, rtol=1e-5)
    np.testing.assert_array_equal(state.N, N)
    batch = jax.tree.map(lambda x: jnp.stack([x, x]), state)  # V of a batch of states (as the runner holds them)
    np.testing.assert_array_equal(batch.V, np.stack([state.V, state.V]))


# ---------------------------------------------------------------------------------------------------------------
# Acting, masks, random agent, registry, hyperparameter domains
# ---------------------------------------------------------------------------------------------------------------


@pytest.mark.statistical(p=1e-7)
def test_greedy_ties_are_uniform_over_valid_actions():
    # 6000 draws tied between actions 0 and 2: the count of action 0 is Binomial(6000, 1/2) given that every draw is
    # 0 or 2 (asserted exactly). 1 check (tests/stat_checks.py): false-failure probability <= 1e-7.
    keys = jax.random.split(key(0), 6000)
    q = jnp.asarray([1.0, 0.5, 1.0, 1.0])
    mask = jnp.asarray([True, True, True, False])
    a = np.asarray(jax.vmap(greedy_action, in_axes=(0, None, None))(keys, q, mask))
    assert set(a.tolist()) <= {0, 2}
    Checks().binomial(int(np.sum(a == 0)), a.size, 0.5, "action 0 among the tied actions 0 and 2")
    nan = np.asarray(jax.vmap(greedy_action, in_axes=(0, None, None))(keys[:500], q * jnp.nan, mask))
    assert set(nan.tolist()) <= {0, 1, 2}


single_draws = jax.jit(jax.vmap(greedy_action_single_draw, in_axes=(0, None, None)))  # compiled once per shape


@pytest.mark.statistical(p=1e-7)
def test_single_draw_greedy_ties_are_uniform_over_valid_actions():
    # 20 000 draws tied between actions 0 and 2: the count of action 0 is Binomial(20 000, 1/2) given that every draw
    # is 0 or 2 (asserted exactly). 1 check (tests/stat_checks.py): false-failure probability <= 1e-7.
    keys = jax.random.split(key(0), 20_000)
    q = jnp.asarray([1.0, 0.5, 1.0, 1.0, 1.0])
    mask = jnp.asarray([True, True, True, False, False])
    draw = single_draws
    a = np.asarray(draw(keys, q, mask))
    assert set(a.tolist()) <= {0, 2}
    Checks().binomial(int(np.sum(a == 0)), a.size, 0.5, "action 0 among the tied actions 0 and 2")
    assert set(np.asarray(draw(keys[:500], q * jnp.nan, mask)).tolist()) <= {0, 1, 2}
    # A unique maximiser is taken whatever the draw; 17 actions exercise the non-unrolled path.
    assert set(np.asarray(draw(keys[:200], q.at[1].set(2.0), mask)).tolist()) == {1}
    wide = jnp.zeros(17).at[jnp.asarray([3, 16])].set(1.0)
    assert set(np.asarray(draw(keys[:400], wide, jnp.ones(17, bool))).tolist()) == {3, 16}


@pytest.mark.parametrize("A", [3, 20])  # 20: above the unrolling threshold
def test_row_max_reduces_the_last_axis(A):
    x = np.random.default_rng(A).normal(size=(4, 5, A)).astype(np.float32)
    np.testing.assert_array_equal(row_max(jnp.asarray(x)), x.max(-1))
    np.testing.assert_array_equal(row_max(jnp.asarray(x[1, 2])), x[1, 2].max())
    assert np.isnan(row_max(jnp.asarray(x).at[0, 0, 1].set(jnp.nan))[0, 0])


@pytest.mark.parametrize("axis", [0, 1, -1])
def test_max_and_first_argmax_equals_numpy_on_ties_and_infinities(axis):
    # Values on a coarse grid (many exact ties), some -inf and whole -inf lines: numpy's max and its argmax (the
    # first index of the maximum), bit for bit, jitted and under vmap.
    rng = np.random.default_rng(3)
    x = rng.integers(-3, 3, size=(9, 7, 5)).astype(np.float32) / 2
    x[rng.random(x.shape) < 0.2] = -np.inf
    x[:, 2, :] = -np.inf
    x[4] = -np.inf
    best, index = jax.jit(max_and_first_argmax, static_argnums=1)(jnp.asarray(x), axis)
    np.testing.assert_array_equal(best, x.max(axis))
    np.testing.assert_array_equal(index, x.argmax(axis))
    assert index.dtype == jnp.int32
    best, index = jax.vmap(lambda y: max_and_first_argmax(y, 0))(jnp.asarray(x))
    np.testing.assert_array_equal(best, x.max(1))
    np.testing.assert_array_equal(index, x.argmax(1))
    # Past the unrolling limit, jnp.argmax itself; at the limit, still unrolled and the same.
    for n in (128, 130):
        y = rng.integers(-3, 3, size=(n, 4)).astype(np.float32)
        best, index = max_and_first_argmax(jnp.asarray(y), 0)
        np.testing.assert_array_equal(best, y.max(0))
        np.testing.assert_array_equal(index, y.argmax(0))


@pytest.mark.parametrize("n_index", [1, 2, 3])
def test_flat_index_reads_and_writes_equal_numpy_indexing(n_index):
    """read_at / write_at against numpy's table[index] and its assignment, on every index of a [4, 5, 3, 2] table
    and vmapped over members with their own indices."""
    rng = np.random.default_rng(0)
    table = rng.normal(size=(4, 5, 3, 2)).astype(np.float32)
    for index in np.ndindex(table.shape[:n_index]):
        np.testing.assert_array_equal(read_at(jnp.asarray(table), *map(jnp.int32, index)), table[index])
        value = rng.normal(size=table.shape[n_index:]).astype(np.float32)
        expected = table.copy()
        expected[index] = value
        written = write_at(jnp.asarray(table), jnp.asarray(value), *map(jnp.int32, index))
        np.testing.assert_array_equal(written, expected)
    members = rng.normal(size=(6,) + table.shape).astype(np.float32)
    idx = [rng.integers(0, n, size=6).astype(np.int32) for n in table.shape[:n_index]]
    values = rng.normal(size=(6,) + table.shape[n_index:]).astype(np.float32)
    got_read = jax.vmap(read_at)(jnp.asarray(members), *map(jnp.asarray, idx))
    got_write = jax.vmap(write_at)(jnp.asarray(members), jnp.asarray(values), *map(jnp.asarray, idx))
    expected = members.copy()
    for m in range(6):
        i = tuple(int(x[m]) for x in idx)
        np.testing.assert_array_equal(got_read[m], members[m][i])
        expected[m][i] = values[m]
    np.testing.assert_array_equal(got_write, expected)


def test_discounted_greedy_policy_by_enumeration():
    # S = 3, A = 3 with action 2 padded (its junk model would be the best): the policy estimate is the greedy policy
    # of the best of the 2^3 deterministic policies of the real actions, found by solving each one's values.
    S, gamma = 3, 0.9
    rng = np.random.default_rng(5)
    P, R = rng.dirichlet(np.ones(S), size=(S, 3)), rng.random((S, 3))
    R[:, 2] = 10.0
    mask = np.array([True, True, False])
    best_v, best_pi = None, None
    for pi in np.ndindex(2, 2, 2):
        P_pi, R_pi = P[np.arange(S), pi], R[np.arange(S), pi]
        v = np.linalg.solve(np.eye(S) - gamma * P_pi, R_pi)
        if best_v is None or np.all(v >= best_v - 1e-12):
            best_v, best_pi = v, pi
    Q = R[:, :2] + gamma * P[:, :2] @ best_v
    assert np.all(np.abs(Q[:, 0] - Q[:, 1]) > 1e-3)  # no near-ties for float32 to break otherwise
    got = discounted_greedy_policy(jnp.asarray(P, jnp.float32), jnp.asarray(R, jnp.float32), gamma, jnp.asarray(mask))
    np.testing.assert_array_equal(got, np.eye(3)[list(best_pi)])


@pytest.mark.parametrize("name, H", [("q_learning_continuous", None), ("q_learning_episodic", 3)])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_q_learning_keeps_the_mdp_dtype(name, H, dtype):
    # With x64 enabled, a float64 MDP gives float64 tables (no float64 -> float32 scatter and its warning) and a
    # float32 MDP keeps float32 ones.
    agent = agents.get(name)
    with jax.enable_x64(True), warnings.catch_warnings():
        warnings.simplefilter("error")
        mdp = jaxmdp.custom_mdp(np.full((3, 2, 3), 1 / 3), R=np.arange(6.0).reshape(3, 2) / 6, H=H, dtype=dtype)
        res = runner.run(agent, runner.product([mdp], [agent.default_hparams], [0, 1]), 40, log_period=10,
                         n_records=2)
    floats = [x for x in jax.tree.leaves(res.agent_state) if np.issubdtype(x.dtype, np.floating)]
    assert floats and all(x.dtype == np.dtype(dtype) for x in floats) and res.values.dtype == np.dtype(dtype)
    assert int(res.agent_state.N.sum()) == 2 * 40


@pytest.mark.statistical(p=3e-7)
@pytest.mark.parametrize("mask", [[True, True, True, False], [True, False, True, False]])
def test_random_agent_acts_uniformly_on_valid_actions(mask):
    # 6000 draws: each valid action's count is Binomial(6000, 1 / #valid). At most 3 checks (tests/stat_checks.py):
    # false-failure probability <= 3e-7.
    agent = agents.get("random_continuous")
    mdp = jaxmdp.custom_mdp(np.full((2, 4, 2), 0.5), R=np.zeros((2, 4))).replace(action_mask=jnp.asarray(mask))
    state = agent.init(jax.random.key(0), spec_of(mdp, 10), agent.default_hparams)
    keys = jax.random.split(key(1), 6000)
    a = np.asarray(jax.vmap(lambda k: agent.act(k, state, jnp.int32(0), jnp.int32(0)))(keys))
    valid = np.flatnonzero(mask)
    assert set(a.tolist()) <= set(valid.tolist())
    checks = Checks()
    for v in valid:
        checks.binomial(int(np.sum(a == v)), a.size, 1 / valid.size, f"valid action {v}")
    np.testing.assert_allclose(agent.policy(state), np.broadcast_to(np.asarray(mask) / sum(mask), (2, 4)))
    ep = agents.get("random_episodic")
    mdp_e = jaxmdp.custom_mdp(np.full((2, 4, 2), 0.5), R=np.zeros((2, 4)), H=3)
    assert ep.policy(ep.init(jax.random.key(0), spec_of(mdp_e, 10), ep.default_hparams)).shape == (3, 2, 4)


def test_registry():
    assert {"random_episodic", "random_continuous", "q_learning_episodic", "q_learning_continuous"} <= set(
        agents.AGENTS)
    for name, agent in agents.AGENTS.items():
        assert agent.name == name and agents.get(name) is agent
        agent.check_hparams(agent.default_hparams)
    with pytest.raises(ValueError, match="did you mean 'q_learning_episodic'"):
        agents.get("q_learning_episodc")


@pytest.mark.parametrize("agent, field, value", [
    ("q_learning_episodic", "c_1", 0.0),
    ("q_learning_episodic", "c_2", -1.0),
    ("q_learning_episodic", "min_at", 1.2),
    ("q_learning_episodic", "p", 1.0),
    ("q_learning_episodic", "bernstein", 0.5),
    ("q_learning_continuous", "h_weight", 0.0),
    ("q_learning_continuous", "span_approx_weight", float("nan")),
    ("q_learning_continuous", "delta", 0.0),
])
def test_hparam_domains(agent, field, value):
    a = agents.get(agent)
    with pytest.raises(ValueError, match=field):
        a.check_hparams(a.default_hparams.replace(**{field: value}))
    # A stacked grid is checked entry by entry.
    grid = jax.tree.map(lambda x: np.asarray([x, x]), a.default_hparams)
    a.check_hparams(grid)
    with pytest.raises(ValueError, match=field):
        a.check_hparams(grid.replace(**{field: np.asarray([getattr(a.default_hparams, field), value])}))


# ---------------------------------------------------------------------------------------------------------------
# Probes with known answers: each agent's policy estimate must be optimal at the end of the budget and (nearly)
# always over its last quarter. Run on N_LEARN seeds in lockstep drawn from stat_checks (fresh seeds under
# tests/fresh_seed_check.py); a seed that misses the criterion is a failure, and at most
# stat_checks.allowed_failures(N_LEARN, Q_LEARN) of them may fail (tests/stat_checks.py, "Learning tests").
# ---------------------------------------------------------------------------------------------------------------


def bandit(H=None):
    T = np.ones((1, 3, 1))
    mean = np.array([0.2, 0.5, 0.8])[None, :, None]
    return jaxmdp.custom_mdp(T, P0=[1.0], H=H, reward_mean=mean, reward_conc=np.full((1, 3, 1), 10.0))


def chain(episodic, **kw):
    return jaxmdp.make("RiverSwim", episodic=episodic, seed=0, size=4, randomize_actions=False, **kw)


def learn(agent, mdp, hparams, n_steps, seeds):
    """Run in exact mode (a log every step, so the early, suboptimal policies are all charged; a record every step)
    and return, per seed, the normalised regret per step over the last quarter, the total regret and the regret of
    the final policy estimate (continuous: from the MDP's current state, as the indicators define it)."""
    res = runner.run(agent, runner.product([mdp], [hparams], seeds=seeds), n_steps, log_period=1,
                     n_records=n_steps)
    norm, regret = res.column("normalized_cumulative_regret"), res.column("cumulative_regret")
    quarter = n_steps // 4
    return (norm[-1] - norm[-1 - quarter]) / quarter, regret[-1], regret[-1] - regret[-2]


def learned(late, total, final):
    """Per seed: the final policy estimate is optimal and (nearly) always was over the last quarter of the budget."""
    return (final == 0.0) & (late < 0.01)


def learn_seeds(default, n):
    """``n`` consecutive seeds from ``stat_checks.seed(default)`` (fresh ones under ``$JAXMDP_TEST_SEED``)."""
    start = seed(default) % (2**31 - 2**20)
    return range(start, start + n)


Q_AGENTS = {  # label -> (agent, probe MDP, hyperparameters, steps)
    **{f"optimistic-{name}": ("q_learning_continuous", name, None, 20_000)
       for name in ("bandit", "chain", "stochastic chain")},
    # The tuned c_1 belongs to the Bernstein bonus; the Hoeffding bonus c_1 sqrt(H^3 iota / t) needs a smaller one.
    **{f"episodic-{name}-{'bernstein' if b else 'hoeffding'}": (
        "q_learning_episodic", name, dict(bernstein=b, c_1=0.9415278732894797 if b else 0.02), 8_000)
       for name in ("bandit", "chain") for b in (True, False)},
}


def q_learning_passes(label, seeds):
    """Per seed of ``seeds``: whether the agent of ``Q_AGENTS[label]`` learned (``learned``), and the total regrets."""
    name, mdp_name, hp, n_steps = Q_AGENTS[label]
    agent = agents.get(name)
    episodic = agent.episodic
    mdp = {"bandit": bandit(H=3 if episodic else None), "chain": chain(episodic),
           "stochastic chain": chain(episodic, p_lazy=0.2, make_reward_stochastic=True)}[mdp_name]
    late, total, final = learn(agent, mdp, agent.default_hparams.replace(**(hp or {})), n_steps, seeds)
    return learned(late, total, final), total


# Measured per-seed failures of `learned` on 2048 seeds (10**6 to 10**6 + 2047; `PYTHONPATH=$PWD python
# tests/probe_failure_rates.py q_learning --seeds 2048 --chunk 256`, 25 Nov 2026). The failing seeds end with a
# suboptimal final estimate after a near-optimal last quarter (e.g. optimistic-bandit seed 1000785: late regret
# 3e-4 per step, final 0.3), except episodic-bandit-bernstein seed 1000546, on a suboptimal arm through the last quarter
# (0.167 per step). q_u: the Clopper-Pearson bound at miss probability 1e-3 (stat_checks.failure_rate_bound), at most
# 6.4e-3; the tests allow stat_checks.allowed_failures(16, q_u) = 4 failures of N_LEARN = 16 seeds: false-failure
# probability <= 1e-7 each (given q <= q_u).
N_LEARN = 16
MEASURED = {"optimistic-bandit": 1, "optimistic-chain": 0, "optimistic-stochastic chain": 0,
            "episodic-bandit-bernstein": 2, "episodic-bandit-hoeffding": 3, "episodic-chain-bernstein": 0,
            "episodic-chain-hoeffding": 0}
Q_LEARN = {label: failure_rate_bound(failures, 2048) for label, failures in MEASURED.items()}


@pytest.mark.statistical(p=1e-7)
@pytest.mark.parametrize("mdp_name", ["bandit", "chain", "stochastic chain"])
def test_optimistic_q_learning_finds_the_optimal_policy(mdp_name):
    label = f"optimistic-{mdp_name}"
    passed, total = q_learning_passes(label, learn_seeds(1, N_LEARN))
    mostly(passed, Q_LEARN[label], label)
    assert np.all(total > 0)  # it did have to learn: the initial estimate is suboptimal (every seed)


@pytest.mark.statistical(p=1e-7)
@pytest.mark.parametrize("mdp_name, bernstein", [("bandit", True), ("bandit", False), ("chain", True),
                                                 ("chain", False)])
def test_episodic_q_learning_finds_the_optimal_policy(mdp_name, bernstein):
    label = f"episodic-{mdp_name}-{'bernstein' if bernstein else 'hoeffding'}"
    passed, total = q_learning_passes(label, learn_seeds(2, N_LEARN))
    mostly(passed, Q_LEARN[label], label)
    assert np.all(total > 0)


@pytest.mark.parametrize("name, H", [("random_continuous", None), ("random_episodic", 3)])
def test_an_agent_that_does_not_learn_fails_the_criterion_on_every_seed(name, H):
    # The uniform policy estimate of the random agent is never optimal on the bandit: its final regret is positive
    # for every seed (exact), so the probes' tolerance of a few failing seeds cannot let a non-learner pass.
    agent = agents.get(name)
    late, total, final = learn(agent, bandit(H=H), agent.default_hparams, 400, learn_seeds(3, N_LEARN))
    assert not np.any(learned(late, total, final))


@pytest.mark.parametrize("A", [2, 3, 20])  # 20: above the unrolling threshold of dp.greedy
def test_greedy_policy_estimate_against_numpy(A):
    # dp.greedy gives the agents' policy estimates: one-hot on the lowest valid index within atol of the best.
    from jaxmdp import dynamic_programming as dp

    rng = np.random.default_rng(A)
    # Exact float32 values: ties, and near-ties 2^-20 apart that atol = 2^-19 merges.
    q = (rng.integers(0, 3, size=(6, 7, A)) + rng.choice([0.0, 2.0**-20], size=(6, 7, A))).astype(np.float32)
    for mask in (np.ones(A, bool), rng.random(A) < 0.6):
        mask[rng.integers(A)] = True
        for atol in (0.0, 2.0**-19):
            qm = np.where(mask, q, -np.inf)
            want = np.argmax(qm >= qm.max(-1, keepdims=True) - atol, axis=-1)
            got = np.asarray(dp.greedy(jnp.asarray(q), jnp.asarray(mask), atol))
            np.testing.assert_array_equal(got, np.eye(A)[want])
