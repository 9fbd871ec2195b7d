"""Reference mode (docs/agents.md): each of the reference's update rules pinned on a hand-worked transition stream.

Every test feeds a short fixed stream to ``update``/``plan`` of both variants, ``agents.get(name)`` (the papers' rules)
and ``agents.get(name, variant="colosseum")`` (the reference's), and compares the state with numbers worked out in
the test from the rules as docs/agents.md states them, so a test fails if a quirk is missing from reference mode or
leaks into the default.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import agents
import jaxmdp
from agents import psrl_continuous as psc
from agents import q_learning_continuous as qlc
from agents.extended_value_iteration import colosseum_extended_value_iteration, colosseum_optimistic_kernel
from agents.ucrl2 import colosseum_confidence, confidence_widths
from jaxmdp.experiment.agent_interface import Transition, spec_of


def _tr(s, a, r, s2, h=0, terminated=False):
    return Transition(obs=jnp.int32(s), action=jnp.int32(a), reward=jnp.float32(r), next_obs=jnp.int32(s2),
                      h=jnp.int32(h), terminated=jnp.asarray(terminated))


def _spec(S, A, H=None, n_steps=100):
    mdp = jaxmdp.custom_mdp(np.full((S, A, S), 1.0 / S), R=np.zeros((S, A)), H=H)
    return spec_of(mdp, n_steps)


def _feed(agent, state, stream, plan=False):
    update = jax.jit(agent.update)
    for t in stream:
        state = update(state, _tr(*t))
        if plan and bool(agent.needs_plan(state)):
            state = jax.jit(agent.plan)(jax.random.key(1), state)
    return state


def test_registry_variants():
    for name, agent in agents.COLOSSEUM_AGENTS.items():
        assert agents.get(name, variant="colosseum") is agent
        assert agents.get(agent.name) is agent  # "<name>@colosseum" round-trips
        paper = agents.get(name)
        assert (agent is paper) == name.startswith("random")  # the random agents are the same in both variants
        assert agent.episodic == paper.episodic
    with pytest.raises(ValueError, match="has no 'colosseum' variant"):
        agents.get("dqn_episodic", variant="colosseum")
    with pytest.raises(ValueError, match="variant must be"):
        agents.get("ucrl2", variant="reference")


# ---------------------------------------------------------------------------------------------------------------
# Q-learning, episodic (docs/agents.md §2)
# ---------------------------------------------------------------------------------------------------------------

QLE_HP = agents.get("q_learning_episodic").default_hparams.replace(c_1=0.5, c_2=100.0, min_at=0.0)
# (s, a, r, s', h, terminated): the last step of an episode at (1, 1), then twice (0, 0) -> 1 at h = 0.
QLE_STREAM = [(1, 1, 1.0, 0, 1, True), (0, 0, 0.5, 1, 0, False), (0, 0, 0.0, 1, 0, False)]


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_q_learning_episodic_stream(variant):
    agent = agents.get("q_learning_episodic", variant)
    state = _feed(agent, agent.init(jax.random.key(0), _spec(2, 2, H=2), QLE_HP), QLE_STREAM)
    H, c1 = 2.0, 0.5
    iota = math.log(2 * 2 * 100 / 0.05)
    K = math.sqrt(H**7 * 4) * iota  # sqrt(H^7 S A) iota
    if variant == "paper":
        # Counts from 0 (alpha_1 = 1), V starts at H, weights (1 - alpha) Q + alpha target, variance W = 0 here
        # (both next values are V_1(1) = 2): beta_t = c1 (sqrt(H / t (0 + H) iota) + K / t).
        beta1 = c1 * (math.sqrt(H * H * iota) + K)  # step 1 (t = 1, reads V_2 = 0)
        q11 = 1.0 + 0.0 + beta1 / 2
        beta2 = beta1  # step 2 (t = 1, reads V_1(1) = min(H, max(2, q11)) = 2)
        q2 = 0.5 + 2.0 + beta2 / 2
        beta3 = c1 * (math.sqrt(H / 2 * H * iota) + K / 2)  # step 3 (t = 2, alpha = 3/4)
        q3 = 0.25 * q2 + 0.75 * (0.0 + 2.0 + (beta3 - 0.25 * beta2) / 1.5)
        counts, v_untouched = 2, 2.0
    else:
        # Counts from 1 (t = 2 on the first visit), V starts at 0, weights alpha Q + (1 - alpha) target, variance
        # term H (sum V^2 - sum V)^2 / t^2: beta_t = c1 (sqrt((H (s2 - s1)^2 / t^2 + H) iota) + K / t).
        beta1 = c1 * (math.sqrt(H * iota) + K / 2)  # step 1 (t = 2, alpha = 3/4, reads V_2 = 0: sums 0)
        q11 = 0.75 * H + 0.25 * (1.0 + 0.0 + beta1 / 1.5)
        beta2 = c1 * (math.sqrt((H * (4 - 2) ** 2 / 4 + H) * iota) + K / 2)  # step 2: sums 2, 4 (V_1(1) = 2)
        q2 = 0.75 * H + 0.25 * (0.5 + 2.0 + beta2 / 1.5)
        beta3 = c1 * (math.sqrt((H * (8 - 4) ** 2 / 9 + H) * iota) + K / 3)  # step 3: t = 3, alpha = 3/5, sums 4, 8
        q3 = 0.6 * q2 + 0.4 * (0.0 + 2.0 + (beta3 - 0.4 * beta2) / 1.2)
        counts, v_untouched = 3, 0.0
    np.testing.assert_allclose(state.Q[1, 1, 1], q11, rtol=1e-5)
    np.testing.assert_allclose(state.Q[0, 0, 0], q3, rtol=1e-5)
    np.testing.assert_allclose(state.beta[0, 0, 0], beta3, rtol=1e-5)
    np.testing.assert_allclose(state.Q[0, 0, 1], H)  # untouched entries
    assert int(state.N[0, 0, 0]) == counts
    np.testing.assert_allclose(state.V[1, 1], 2.0)  # min(H, max_a Q) with Q_1(1, 0) = 2 < q11
    np.testing.assert_allclose(state.V[0, 1], v_untouched)  # never updated: the initial V
    assert q3 > H  # so V_0(0) = H in both variants
    np.testing.assert_allclose(state.V[0, 0], H)


def test_q_learning_episodic_variants_have_different_tree_structures():
    # The variant is part of the state's tree structure (a static field), so no jit cache can hand one variant's
    # trace to the other: with the variant as a class attribute of a subclass, jax.tree.structure of the two states
    # compared equal (PyTreeDef equality ignored the dataclass's class), and this module's stream test once ran the
    # paper rules on the colosseum state in a full-suite run.
    spec = _spec(2, 2, H=2)
    paper, colosseum = (agents.get("q_learning_episodic", v).init(jax.random.key(0), spec, QLE_HP)
                        for v in ("paper", "colosseum"))
    assert (paper.variant, colosseum.variant) == ("paper", "colosseum")
    assert jax.tree.structure(paper) != jax.tree.structure(colosseum)
    # Both variants through one jitted update, colosseum first and then paper: each runs its own rules.
    update = jax.jit(agents.get("q_learning_episodic").update)
    tr = _tr(*QLE_STREAM[0])
    for state in (colosseum, paper):
        got = update(state, tr)
        want = agents.get("q_learning_episodic").update(state, tr)  # eager: traced anew for each state
        assert got.variant == state.variant
        np.testing.assert_allclose(got.q, want.q, rtol=1e-6)
    assert not np.allclose(update(colosseum, tr).q, update(paper, tr).q)  # the two rules differ on this step


def _replay_reference_q_learning(stream, S, A, horizon, n_steps, hp):
    """A plain float64 replay of the reference's episodic Q-learning (docs/agents.md §2, reference mode), with its
    stored ``V[horizon + 1, S]`` refreshed after every update, step by step: ``[(Q, N, beta, V)]`` after each step."""
    H = float(horizon)
    iota = math.log(S * A * n_steps / float(hp.p))
    Q, N = np.full((horizon, S, A), H), np.ones((horizon, S, A))
    mu, sigma, beta = np.zeros((horizon, S, A)), np.zeros((horizon, S, A)), np.zeros((horizon, S, A))
    V = np.zeros((horizon + 1, S))
    out = []
    for s, a, r, s2, h, _ in stream:
        N[h, s, a] += 1
        t = N[h, s, a]
        alpha = max(float(hp.min_at), (H + 1) / (H + t))
        mu[h, s, a] += V[h + 1, s2]
        sigma[h, s, a] += V[h + 1, s2] ** 2
        new_beta = min(float(hp.c_1) * (math.sqrt((H * (sigma[h, s, a] - mu[h, s, a]) ** 2 / t**2 + H) * iota)
                                        + math.sqrt(H**7 * S * A) * iota / t),
                       float(hp.c_2) * math.sqrt(H**3 * iota / t))
        if hp.bernstein:
            b = (new_beta - (1 - alpha) * beta[h, s, a]) / (2 * alpha)
        else:
            b = float(hp.c_1) * math.sqrt(H**3 * iota / t)
        beta[h, s, a] = new_beta
        Q[h, s, a] = alpha * Q[h, s, a] + (1 - alpha) * (r + V[h + 1, s2] + b)
        V[h, s] = min(H, Q[h, s].max())
        out.append((Q.copy(), N.copy(), beta.copy(), V.copy()))
    return out


@pytest.mark.parametrize("bernstein", [True, False])
@pytest.mark.parametrize("horizon", [3, 2])  # 2: a member whose horizon is shorter than the table's (H = 3)
def test_q_learning_episodic_reference_values_match_a_replay(horizon, bernstein):
    # The reference stores V beside Q; reference mode reads it off the table (V_h(s) = 0 until the first update at
    # (h, s), then min(H, max_a Q_h(s, a))). A plain replay of the stored-V rule checks that reading after every
    # step. Small c_1, c_2 and rewards keep Q below H once updated, so V_h(s) lies strictly between 0 and H where
    # every action of (h, s) was updated; state 3 only starts episode 10 (one update, at h = 0; never updated at
    # h >= 1, where its V stays 0), and every first visit of a next state reads the initial V = 0.
    S, A, n_steps = 4, 2, 500
    rng = np.random.default_rng(7)
    stream = []
    for episode in range(30):
        s = 3 if episode == 10 else int(rng.integers(3))
        for h in range(horizon):
            a, s2 = int(rng.integers(A)), int(rng.integers(3))
            stream.append((s, a, round(float(rng.random()) * 0.3, 3), s2, h, h == horizon - 1))
            s = s2
    hp = QLE_HP.replace(c_1=0.01, c_2=0.02, min_at=0.05, bernstein=bernstein)
    agent = agents.get("q_learning_episodic", "colosseum")
    spec = _spec(S, A, H=3, n_steps=n_steps).replace(horizon=jnp.int32(horizon))
    state = agent.init(jax.random.key(0), spec, hp)
    update = jax.jit(agent.update)
    expected = _replay_reference_q_learning(stream, S, A, horizon, n_steps, hp)
    for tr, (Q, N, beta, V) in zip(stream, expected):
        state = update(state, _tr(*tr))
        got_V = np.asarray(state.V)
        np.testing.assert_array_equal(got_V[:horizon] == 0.0, V[:horizon] == 0.0)  # never-updated pairs read 0
        np.testing.assert_allclose(got_V[:horizon], V[:horizon], rtol=2e-5)
        np.testing.assert_array_equal(got_V[horizon:], 0.0)
    np.testing.assert_allclose(state.Q[:horizon], Q, rtol=2e-5)
    np.testing.assert_array_equal(state.N[:horizon], N)
    np.testing.assert_allclose(state.beta[:horizon], beta, rtol=2e-5, atol=1e-7)
    # The stream has what the test is for: state 3 updated once at h = 0 (V_0(3) = H: its other action is
    # untouched) and never after, V strictly inside (0, H) elsewhere.
    assert np.sum(N[0, 3]) == A + 1 and np.all(N[1:, 3] == 1)
    np.testing.assert_array_equal(V[:, 3], [horizon] + [0.0] * horizon)
    assert np.any((V[:horizon] > 0) & (V[:horizon] < horizon))
    # Q stayed the reference's: the paper's rules on the same stream give another table.
    paper = _feed(agents.get("q_learning_episodic"), agents.get("q_learning_episodic").init(jax.random.key(0), spec,
                                                                                             hp), stream)
    assert not np.allclose(paper.Q[:horizon], Q, rtol=1e-3)


# ---------------------------------------------------------------------------------------------------------------
# Optimistic Q-learning, continuous (docs/agents.md §5)
# ---------------------------------------------------------------------------------------------------------------


def test_q_learning_continuous_constants():
    # sp = 1, S A = 2, T = 1000: the cube-root branch of H is the smaller one.
    hp = qlc.QLearningContinuousHParams(h_weight=1.0, span_approx_weight=1.0, min_at=0.0)
    assert agents.get("q_learning_continuous", "colosseum").default_hparams.delta == 0.95  # the reference's
    assert agents.get("q_learning_continuous").default_hparams.delta == 0.05  # "confidence" stands for delta
    for variant, delta, third in (("paper", 0.05, 1 / 3), ("colosseum", 0.95, 0.333)):
        H, gamma, bonus, _ = qlc.constants(hp.replace(delta=delta), 2, 1, 1000, variant=variant)
        H_hand = (1000 / (2 * math.log(4000 / delta))) ** third
        assert H_hand < math.sqrt(1000 / 2)
        np.testing.assert_allclose(H, H_hand, rtol=1e-6)
        np.testing.assert_allclose(gamma, 1 - 1 / H_hand, rtol=1e-6)
        np.testing.assert_allclose(bonus, 4 * math.sqrt(H_hand * math.log(2000 / delta)), rtol=1e-6)
    # A tiny h_weight: the paper's H is floored at 1, the reference's is not (its gamma goes negative).
    tiny = hp.replace(h_weight=0.1, delta=0.95)
    np.testing.assert_allclose(qlc.constants(tiny, 2, 1, 1000)[0], 1.0)
    H_ref, gamma_ref, *_ = qlc.constants(tiny, 2, 1, 1000, variant="colosseum")
    np.testing.assert_allclose(H_ref, 0.1 * (1000 / (2 * math.log(4000 / 0.95))) ** 0.333, rtol=1e-6)
    assert float(gamma_ref) < 0


# S = 2, A = 1 (V(s) is Q_hat(s, 0)): (s, a, r, s').
QLC_STREAM = [(0, 0, 0.0, 1), (0, 0, 1.0, 1), (1, 0, 0.5, 0), (0, 0, 0.0, 0)]


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_q_learning_continuous_stream(variant):
    agent = agents.get("q_learning_continuous", variant)
    # The same constants in both variants (H = sqrt(sp T / (S A)) = sqrt(5), the square-root branch; delta 0.95).
    hp = qlc.QLearningContinuousHParams(h_weight=1.0, span_approx_weight=0.01, min_at=0.0, delta=0.95)
    state = _feed(agent, agent.init(jax.random.key(0), _spec(2, 1, n_steps=1000), hp), QLC_STREAM)
    H = math.sqrt(5.0)
    g = 1 - 1 / H
    bs = 0.04 * math.sqrt(H * math.log(2000 / 0.95))  # bonus at tau = 1
    alpha = lambda tau: (H + 1) / (H + tau)  # noqa: E731
    q1 = g * H + bs  # step 1: tau = 1, alpha = 1, V(1) = H
    q2 = (1 - alpha(2)) * q1 + alpha(2) * (1.0 + g * H + bs / math.sqrt(2))  # step 2: above q1, Q_hat(0) stays q1
    assert q1 < H and q2 > q1
    if variant == "paper":
        # V refreshed at s: V(0) = q1 after step 1; the running estimate of (0, 0) continues from q2.
        q3 = 0.5 + g * q1 + bs  # step 3 reads V(0) = q1
        q4 = (1 - alpha(3)) * q2 + alpha(3) * (g * q1 + bs / math.sqrt(3))
        V = [min(q1, q4), min(H, q3)]
    else:
        # V refreshed at s': V(0) stays H until step 3 leads to 0; the running update restarts from Q_hat = q1.
        q3 = 0.5 + g * H + bs
        q4 = (1 - alpha(3)) * q1 + alpha(3) * (g * q1 + bs / math.sqrt(3))  # V(0) = Q_hat(0) = q1 after step 3
        V = [min(q1, q4), H]  # V(1) was last refreshed by step 2 (s' = 1), before step 3 changed Q_hat(1)
    np.testing.assert_allclose(state.Q[:, 0], [q4, q3], rtol=1e-5)  # running estimates
    np.testing.assert_allclose(state.Q_hat[:, 0], [min(q1, q4), min(H, q3)], rtol=1e-5)
    np.testing.assert_allclose(state.V, V, rtol=1e-5)
    np.testing.assert_array_equal(state.N[:, 0], [3, 1])


# ---------------------------------------------------------------------------------------------------------------
# UCRL2 (docs/agents.md §3)
# ---------------------------------------------------------------------------------------------------------------


def test_colosseum_optimistic_kernel_by_hand():
    p = jnp.asarray([0.2, 0.5, 0.3, 0.0])
    mask = jnp.asarray([True, True, True, False])  # state 3 padded
    u = jnp.asarray([0.0, 2.0, 1.0, 0.0])  # increasing order 0, 2, 1: the best state b = 1
    kernel = lambda w, u=u: np.asarray(colosseum_optimistic_kernel(p, jnp.asarray(w), u, mask))  # noqa: E731
    # width 0.4: m = 0.5 + 0.2 = 0.7, excess 0.2 taken from state 0 (the lowest u).
    np.testing.assert_allclose(kernel(0.4), [0.0, 0.7, 0.3, 0.0], atol=1e-7)
    # width 0.6: m = 0.8, excess 0.3: state 0 gives its 0.2, state 2 the remaining 0.1.
    np.testing.assert_allclose(kernel(0.6), [0.0, 0.8, 0.2, 0.0], atol=1e-7)
    # width 0.1: m = 0.55, excess 0.05 from state 0.
    np.testing.assert_allclose(kernel(0.1), [0.15, 0.55, 0.3, 0.0], atol=1e-7)
    # width 1.2: m = 1, the point mass on b.
    np.testing.assert_allclose(kernel(1.2), [0.0, 1.0, 0.0, 0.0], atol=1e-7)
    # u = 0 (the first sweep): the identity order, b = the last real state (2), never the padded one.
    np.testing.assert_allclose(kernel(0.2, jnp.zeros(4)), [0.1, 0.5, 0.4, 0.0], atol=1e-7)
    # The paper's box (per-next-state width 0.4) for comparison: lo = (0, 0.1, 0, 0), the budget 0.9 fills state 1
    # up to 0.9 then state 2: a different kernel.
    from agents.extended_value_iteration import confidence_box, optimistic_kernel

    lo, hi = confidence_box(p, jnp.full(4, 0.4), mask)
    np.testing.assert_allclose(optimistic_kernel(lo, hi, u), [0.0, 0.9, 0.1, 0.0], atol=1e-7)


def test_colosseum_evi_by_hand():
    S, A = 2, 2
    p = jnp.full((S, A, S), 0.5)
    width = jnp.zeros((S, A))  # p~ = p
    ones = jnp.ones(S, bool), jnp.ones(A, bool)
    r = jnp.asarray([[0.2, 0.6], [0.4, 0.1]])
    res = colosseum_extended_value_iteration(p, width, r, *ones)
    # Sweep 1 (u = 0): u' = (0.6, 0.4), span 0.2. Sweep 2 (u = (0.2, 0), p~ u = 0.1): Q = r + 0.1 - u(s), u' - u =
    # (0.5, 0.5): stop with that Q.
    assert int(res.iterations) == 2 and bool(res.converged)
    np.testing.assert_allclose(res.Q, [[0.1, 0.5], [0.5, 0.2]], atol=1e-6)
    # The running maximum: a later action within tol (1e-3) of it replaces it. One sweep: u'(1) = 0.3995, not 0.4.
    r2 = r.at[1, 1].set(0.3995)
    one = colosseum_extended_value_iteration(p, width, r2, *ones, max_iter=1)
    assert not bool(one.converged)
    np.testing.assert_allclose(one.u, [0.6 - 0.3995, 0.0], atol=1e-6)
    np.testing.assert_allclose([one.gain_lower, one.gain_upper], [0.3995, 0.6], atol=1e-6)
    # Two absorbing states of different gains: the span never shrinks, no convergence (no aperiodicity transform).
    stay = jnp.asarray([[[1.0, 0.0]] * 2, [[0.0, 1.0]] * 2])
    bad = colosseum_extended_value_iteration(stay, width, r, *ones, max_iter=50)
    assert int(bad.iterations) == 50 and not bool(bad.converged)


def test_colosseum_confidence_closed_form():
    # Every entry of the reference's widths from its formulas (docs/agents.md §3), at an arbitrary lagged model,
    # visits and iteration, with alpha_p, alpha_r, r_max away from 1 (the stream test below pins two entries).
    S, A = 3, 2
    rng = np.random.default_rng(3)
    agent = agents.get("ucrl2", "colosseum")
    hp = agent.default_hparams.replace(alpha_p=0.7, alpha_r=0.4, r_max=2.0)
    state = agent.init(jax.random.key(0), _spec(S, A), hp)
    P, R = rng.dirichlet(np.ones(S), size=(S, A)), rng.random((S, A)) * 2.0
    visits = np.array([[0, 1], [2, 7], [40, 3]])
    state = state.replace(p_model=jnp.asarray(P, jnp.float32), r_model=jnp.asarray(R, jnp.float32),
                          schedule=state.schedule.replace(visits=jnp.asarray(visits, jnp.int32)),
                          iteration=jnp.int32(57))
    width, r_tilde = (np.asarray(x, np.float64) for x in colosseum_confidence(state))
    delta = 1 / math.sqrt(57 + 1)
    L = math.log(2 * S * A * (57 + 1) / delta)
    n1, n2 = np.maximum(visits, 1), np.maximum(visits - 1, 1)
    p0 = P[..., 0]
    np.testing.assert_allclose(width, math.sqrt(0.7) * np.sqrt(14 * p0 * (1 - p0) / n1 * L) + 0.7 * 49 * L / (3 * n2),
                               rtol=1e-5)
    np.testing.assert_allclose(r_tilde, np.minimum(2.0, R + 0.4 * 2.0 * np.sqrt(3.5 * L / n1)), rtol=1e-5)
    assert np.any(r_tilde < 2.0)  # the cap does not hide the reward width everywhere


# (s, a, r, s'): each step ends an epoch (first visits of (0, 1) and (1, 0), then N(1, 0) = 2 with nu = 1).
UCRL2_STREAM = [(0, 1, 0.5, 1), (1, 0, 0.2, 1), (1, 0, 0.4, 0)]


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_ucrl2_stream(variant):
    agent = agents.get("ucrl2", variant)
    hp = agent.default_hparams.replace(alpha_r=0.05, alpha_p=1.0)
    state = jax.jit(agent.plan)(jax.random.key(0), agent.init(jax.random.key(0), _spec(2, 2), hp))
    state = _feed(agent, state, UCRL2_STREAM[:2], plan=True)
    before = _feed(agent, state, UCRL2_STREAM[2:])  # the third epoch end, before its plan
    after = jax.jit(agent.plan)(jax.random.key(1), before)
    L = lambda n: math.log(2 * 2 * 2) + 1.5 * math.log(n + 1)  # noqa: E731  ln(2SA(n+1)/delta), delta = (n+1)^-1/2
    if variant == "paper":
        # Up-to-date empirical means, t counts every step (3).
        np.testing.assert_allclose(before.reward_mean[1, 0], 0.3, rtol=1e-6)
        _, width_p, r_tilde = confidence_widths(before)
        np.testing.assert_allclose(r_tilde[1, 0], 0.3 + 0.05 * math.sqrt(3.5 * L(3) / 2), rtol=1e-5)
        ph = np.array([0.5, 0.5])  # N(1, 0, .) = (1, 1): per-next-state Bernstein widths
        np.testing.assert_allclose(width_p[1, 0], np.sqrt(14 * ph * (1 - ph) / 2 * L(3)) + 49 * L(3) / 3, rtol=1e-5)
        return
    # Reference mode. After the second epoch: iteration = 2, the model folded up to the second epoch:
    # r_model(0, 1) = (1 * 2 + 0.5) / 3, r_model(1, 0) = (2 + 0.2) / 3, p_model rows of the counts, others untouched.
    assert int(before.iteration) == 2
    r10 = (2 + 0.2) / 3
    np.testing.assert_allclose(before.r_model, [[1.0, 2.5 / 3], [r10, 1.0]], rtol=1e-6)
    np.testing.assert_allclose(before.p_model, [[[0.5, 0.5], [0.0, 1.0]], [[0.0, 1.0], [0.5, 0.5]]], atol=1e-7)
    # The third plan uses that lagged model, the up-to-date count N(1, 0) = 2 and the lagged iteration 2; the
    # transition width is that of next state 0 (p_model(0 | 1, 0) = 0): alpha_p 49 L / (3 max(1, N - 1)).
    width, r_tilde = colosseum_confidence(before)
    np.testing.assert_allclose(r_tilde[1, 0], r10 + 0.05 * math.sqrt(3.5 * L(2) / 2), rtol=1e-5)
    np.testing.assert_allclose(width[1, 0], 49 * L(2) / 3, rtol=1e-5)
    np.testing.assert_allclose(r_tilde[0, 0], 1.0)  # unvisited: r_max
    p0 = 0.5  # (0, 0) unvisited: the uniform initial model, N' = N'' = 1
    np.testing.assert_allclose(width[0, 0], math.sqrt(14 * p0 * (1 - p0) * L(2)) + 49 * L(2) / 3, rtol=1e-5)
    # Then the fold: N = 2, nu = 1: r_model(1, 0) = (r10 (N + 1) + 0.4) / (N + nu + 1); p_model(1, 0) = (1/2, 1/2).
    assert int(after.iteration) == 3
    np.testing.assert_allclose(after.r_model[1, 0], (r10 * 3 + 0.4) / 4, rtol=1e-6)
    np.testing.assert_allclose(after.p_model[1, 0], [0.5, 0.5], atol=1e-7)
    np.testing.assert_allclose(after.epoch_rewards, 0.0)
    # The policy estimate plans on the lagged model; EVI failing keeps the previous epoch's Q.
    sentinel = jnp.full_like(before.Q, 7.0)
    stuck = before.replace(Q=sentinel, r_model=before.r_model.at[0].set(0.0), hparams=hp.replace(evi_max_iter=1))
    stuck = agent.plan(jax.random.key(1), stuck)
    assert not bool(stuck.evi_converged)
    assert int(stuck.plans_unconverged) == int(before.plans_unconverged) + 1  # the runner's diagnostic counts it
    np.testing.assert_array_equal(stuck.Q, sentinel)


# ---------------------------------------------------------------------------------------------------------------
# PSRL, episodic (docs/agents.md §1)
# ---------------------------------------------------------------------------------------------------------------


def _log_of_concentration(key, alpha):
    """A deterministic "Gamma sampler": g = alpha (so a Dirichlet draw is alpha / sum alpha, or / (sum + 1e-5))."""
    del key
    return jnp.log(alpha)


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_psrl_episodic_stream(variant):
    agent = agents.get("psrl_episodic", variant)
    # A tiny transition prior makes the reference's sum + 1e-5 visible; a huge reward precision makes reward draws
    # their means (std ~ 1e-6).
    hp = agent.default_hparams.replace(transition_prior=1e-6, prior_mean=0.5, reward_prior_precision=1e12)
    state = agent.init(jax.random.key(0), _spec(2, 1, H=2), hp).replace(plan_due=jnp.zeros((), bool))
    # One episode: 0 -> 0 (h = 0), then 0 -> 0 again at the last step (h = 1). The paper's rule learns that second
    # transition; the reference's code of the published numbers counts its terminal observation -1 as numpy's x[-1],
    # a visit to the last state, 1.
    state = _feed(agent, state, [(0, 0, 0.5, 0, 0, False), (0, 0, 0.5, 0, 1, True)])
    learns_final = variant == "paper"
    np.testing.assert_array_equal(state.counts[0, 0], [2, 0] if learns_final else [1, 1])
    assert bool(agent.needs_plan(state))
    state = agent.plan(jax.random.key(1), state, _log_of_concentration)
    # Rewards 0.5 everywhere. Row of state 1 (unvisited): alpha = (1e-6, 1e-6). Row of state 0: alpha = (2 + 1e-6,
    # 1e-6) (paper) or (1 + 1e-6, 1 + 1e-6) (reference).
    alpha0 = np.array([2 + 1e-6, 1e-6]) if learns_final else np.array([1 + 1e-6, 1 + 1e-6])
    alpha1 = np.array([1e-6, 1e-6])
    offset = 0.0 if variant == "paper" else 1e-5
    P = np.stack([alpha0 / (alpha0.sum() + offset), alpha1 / (alpha1.sum() + offset)])
    V1 = np.full(2, 0.5)  # the last step: the reward only
    np.testing.assert_allclose(state.Q[1, :, 0], V1, rtol=1e-4)
    np.testing.assert_allclose(state.Q[0, :, 0], 0.5 + P @ V1, rtol=1e-4)
    if variant == "colosseum":
        np.testing.assert_allclose(state.Q[0, 1, 0], 0.5 + 0.5 * 2e-6 / 1.2e-5, rtol=1e-4)  # a row of mass 1/6


# ---------------------------------------------------------------------------------------------------------------
# PSRL, continuous (docs/agents.md §4)
# ---------------------------------------------------------------------------------------------------------------


def test_colosseum_extended_rewards_by_hand():
    R = jnp.asarray([[0.1, 0.5, 0.9]])
    # psi = 2 of a buffer of 3 (slot 2 repeats slot 0): extended action j = a psi + k gets R[j mod A].
    np.testing.assert_allclose(psc.colosseum_extended_rewards(R, jnp.int32(2), 3, jnp.ones(3, bool)),
                               [[0.1, 0.5, 0.1, 0.9, 0.1, 0.9, 0.5, 0.9, 0.5]])
    # A padded third action (A = 2): j mod 2; the padded action repeats action 0.
    np.testing.assert_allclose(psc.colosseum_extended_rewards(R, jnp.int32(2), 3, jnp.asarray([True, True, False])),
                               [[0.1, 0.5, 0.1, 0.1, 0.5, 0.1, 0.1, 0.5, 0.1]])


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_psrl_continuous_plan_rewards(variant):
    # One state, two actions: every kernel is the self-loop, so V = max R / (1 - 0.99) and Q_ext(a, k) = R(reward
    # index) + 0.99 V. With psi = 2 and A = 2 the reference rewards (a, k) with action k's draw: both actions reach
    # max R = 0.9; the paper's action 0 has its own 0.1.
    agent = agents.get("psrl_continuous", variant)
    hp = agent.default_hparams.replace(max_psi=2)
    state = agent.init(jax.random.key(0), _spec(1, 2, n_steps=1000), hp)
    assert int(state.constants.psi) == 2
    ng = state.rewards
    state = state.replace(rewards=ng.replace(mu=jnp.asarray([[0.1, 0.9]]), lam=jnp.full((1, 2), 1e12),
                                             alpha=jnp.full((1, 2), 1e6), beta=jnp.full((1, 2), 1e6)))
    Q = agent.plan(jax.random.key(3), state).Q
    expected = [90.0, 90.0] if variant == "colosseum" else [0.1 + 0.99 * 90.0, 90.0]
    np.testing.assert_allclose(Q[0], expected, rtol=1e-3)


@pytest.mark.parametrize("kernels", ["paper", "colosseum"])
@pytest.mark.parametrize("rewards", ["paper", "colosseum"])
def test_psrl_continuous_plan_reward_variant_alone(kernels, rewards):
    # The one-state MDP of the test above: the extended rewards follow reward_variant whatever the kernels' rule.
    hp = agents.get("psrl_continuous").default_hparams.replace(max_psi=2)
    state = psc.init(jax.random.key(0), _spec(1, 2, n_steps=1000), hp)
    state = state.replace(rewards=state.rewards.replace(
        mu=jnp.asarray([[0.1, 0.9]]), lam=jnp.full((1, 2), 1e12), alpha=jnp.full((1, 2), 1e6),
        beta=jnp.full((1, 2), 1e6)))
    Q = psc.plan(jax.random.key(3), state, variant=kernels, reward_variant=rewards).Q
    expected = [90.0, 90.0] if rewards == "colosseum" else [0.1 + 0.99 * 90.0, 90.0]
    np.testing.assert_allclose(Q[0], expected, rtol=1e-3)
    with pytest.raises(ValueError, match="reward_variant must be"):
        psc.plan(jax.random.key(3), state, variant=kernels, reward_variant="reference")


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
def test_psrl_continuous_simple_optimistic_sampling(variant):
    agent = agents.get("psrl_continuous", variant)
    S, A = 10, 2
    hp = agent.default_hparams.replace(eta_weight=1.0, max_psi=2)  # eta = min(10 S, ...) = 100: simple sampling
    state = agent.init(jax.random.key(0), _spec(S, A, n_steps=1000), hp)
    assert float(state.constants.eta) == 100.0 and int(state.constants.psi) == 2
    stream = [(0, 0, 0.0, 0)] * 60 + [(0, 0, 0.0, 1)] * 20  # N(0, 0, .) = (60, 20, 0, ...)
    state = _feed(agent, state.replace(plan_due=jnp.zeros((), bool)), stream)
    P = np.asarray(psc.candidate_kernels(jax.random.key(4), state, variant=variant), np.float64)  # [psi, S, A, S]
    # Deviation sqrt(3 p ln(4S) / n) + 3 ln(4S) / n with n = N(s, a) = 80 (paper) or N(s, a, s') (reference).
    p_hat = np.array([0.75, 0.25] + [0.0] * 8)
    n = np.full(S, 80.0) if variant == "paper" else np.array([60.0, 20.0] + [1.0] * 8)
    log4s = math.log(4 * S)
    p_minus = p_hat - np.minimum(np.sqrt(3 * p_hat * log4s / n) + 3 * log4s / n, p_hat)
    assert (p_minus[0] > 0.1) and (p_minus[1] == 0)  # (0.290, 0) paper; (0.194, 0) reference
    receivers = []
    for k in range(2):
        row = P[k, 0, 0]
        extra = row - p_minus
        z = int(np.argmax(extra))
        np.testing.assert_allclose(np.delete(extra, z), 0.0, atol=1e-6)
        np.testing.assert_allclose(extra[z], 1 - p_minus.sum(), rtol=1e-5)
        # Unvisited pairs: all their mass on the receiving state.
        receivers.append(np.argmax(P[k].reshape(S * A, S)[1:], axis=-1))
        np.testing.assert_allclose(P[k].reshape(S * A, S)[1:].max(-1), 1.0)
        assert receivers[-1].shape == (S * A - 1,) and z in range(S)
        if variant == "colosseum":
            assert np.all(receivers[-1] == z)  # one receiving state per candidate, shared by all pairs
    if variant == "paper":
        # Independent receivers per pair: 19 draws uniform over 10 states all equal with probability 10^-18 per
        # candidate (false-failure probability 2e-18).
        assert all(len(set(r.tolist())) > 1 for r in receivers)
