"""Beta rewards: the step's rewards against the MDP's mean table R, and the step's sampler jaxmdp.sampling.beta_shared
with its unrolled Threefry hash: the hash against jax's, exactness against scipy, the round logic (failure rate against
its exact value), the stream's independence from the key's jax.random stream, float64 and rbg keys, edge shapes, and
batch members against single calls (sampler and step), bit for bit."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.extend.random import threefry2x32_p
from scipy import integrate, stats

import jaxmdp
import jaxmdp.sampling.beta_shared as beta_module
from jaxmdp.sampling.beta_shared import sample_beta_shared as sample_beta
from jaxmdp.sampling.beta_sampling import shape_terms
from jaxmdp.sampling.threefry import threefry2x32
from stat_checks import Checks, key


def test_threefry_equals_jax_bitwise():
    words = np.random.default_rng(0).integers(0, 2**32, (4, 5000), dtype=np.uint64).astype(np.uint32)
    words[:, :4] = [[0, 0, 2**32 - 1, 1], [0, 2**32 - 1, 2**32 - 1, 0], [0, 0, 2**32 - 1, 7], [0, 1, 2**32 - 1, 0]]
    ours = jax.jit(threefry2x32)(*map(jnp.asarray, words))
    theirs = threefry2x32_p.bind(*map(jnp.asarray, words))
    for o, t in zip(ours, theirs):
        np.testing.assert_array_equal(o, t)
    # Scalars broadcast against arrays (a key against many counters), as in the sampler.
    k0, k1 = jnp.uint32(123), jnp.uint32(456)
    ours = threefry2x32(k0, k1, jnp.asarray(words[2]), jnp.asarray(words[3]))
    theirs = threefry2x32_p.bind(jnp.full(5000, k0), jnp.full(5000, k1), jnp.asarray(words[2]), jnp.asarray(words[3]))
    for o, t in zip(ours, theirs):
        np.testing.assert_array_equal(o, t)


def acceptance(shape: float) -> float:
    """Exact acceptance probability of a Marsaglia-Tsang trial at a shape (boosted to ``a + 1`` below one), by
    quadrature: ``P(accept | x) = P(w < t(x)) = t(x)`` where ``1 + c x > 0`` (``t <= 1``; the squeeze lies inside)."""
    a = shape + 1.0 if shape < 1.0 else shape
    d = a - 1.0 / 3.0
    c = 1.0 / np.sqrt(9.0 * d)

    def density(x):
        v = (1.0 + c * x) ** 3
        return stats.norm.pdf(x) * np.exp(0.5 * x * x + d * (1.0 - v + np.log(v)))

    # N(0, 1) mass beyond 12: 4e-33.
    return integrate.quad(density, max(-1.0 / c, -12.0), 12.0, epsabs=1e-13, epsrel=1e-12, limit=200)[0]


def round_failure(p_a: float, p_b: float, n: int) -> float:
    """P(a round of n trials does not accept both): ``G_a`` takes the first trial accepted for ``a``, ``G_b`` the first
    later one accepted for ``b``; the round fails iff ``J_a + J_b > n`` (independent geometric waits)."""
    success = sum(p_a * (1 - p_a) ** (j - 1) * (1 - (1 - p_b) ** (n - j)) for j in range(1, n))
    return 1.0 - success


def test_acceptance_matches_the_documented_worst_case():
    # Deterministic (quadrature): the module docstrings' 0.9517 at a' = 1 and the round failure bounds it implies.
    assert abs(acceptance(1.0) - 0.9517) < 5e-5
    assert all(acceptance(a) > acceptance(1.0) for a in (0.01, 0.5, 1.5, 2.4, 20.0, 249.0))
    p = acceptance(1.0)
    assert abs(round_failure(p, p, 4) - 4.4e-4) < 0.05e-4 and abs(round_failure(p, p, 5) - 2.6e-5) < 0.05e-5


@functools.partial(jax.jit, static_argnames="n")
def failed_rounds(keys, a, b, n):
    """Per key: whether round 0 of ``n`` trials did not accept both Gammas (shapes ``a``, ``b``: scalars, or one pair
    per key)."""
    a, b = (jnp.broadcast_to(x, keys.shape) for x in (a, b))

    def failed(k, x, y):  # (the scalar round of beta_shared)
        return beta_module._round(k, jnp.int32(0), n, jnp.stack([x, y]), (shape_terms(x), shape_terms(y))) < 0

    return jax.vmap(failed)(keys, a, b)


@pytest.mark.statistical(p=1e-7)
@pytest.mark.parametrize("a, b, n", [(1.0, 1.0, 4), (1.0, 1.0, 2), (0.01, 2.4, 3), (35.0, 0.8, 2)])
def test_round_failure_rate_is_exact(a, b, n):
    # The count of failed rounds among N keys is exactly Binomial(N, round_failure): checks the order in which trials
    # go to G_a and G_b (giving a trial to both, or trial 0 to G_b, changes the rate) and the failure rates the module
    # docstring states. The normal deviate stops at 5.4 (P = 7e-8), which moves the rate by far less than its
    # binomial spread. 1 check: false-failure probability <= 1e-7.
    N = 1_000_000
    keys = jax.random.split(key(31), N)
    fails = int(jnp.sum(failed_rounds(keys, jnp.float32(a), jnp.float32(b), n)))
    Checks().binomial(fails, N, round_failure(acceptance(a), acceptance(b), n), f"failed rounds, Beta({a}, {b}), n={n}")


@pytest.mark.statistical(p=2e-7)
def test_draws_are_independent_of_the_key_own_stream():
    # The sampler's counters never meet jax.random's on the same key: u = uniform(key) and F(x) (F the exact CDF of
    # the draw x of the same key) are independent uniforms, so the count of keys with both on the same side of 1/2 is
    # Binomial(n, 1/2); likewise for the step's own use of the key (split). 2 checks: <= 2e-7.
    n, a, b = 100_000, 2.4, 24.0
    keys = jax.random.split(key(32), n)
    x = np.asarray(jax.jit(jax.vmap(lambda k: sample_beta(k, a, b)))(keys), np.float64)
    u = np.asarray(jax.vmap(jax.random.uniform)(keys), np.float64)
    k1 = jax.vmap(lambda k: jax.random.uniform(jax.random.split(k)[0]))(keys)
    checks = Checks()
    cdf = stats.beta(a, b).cdf(x)
    checks.independent_signs(u, cdf, 0.5, 0.5, "uniform(key) against the draw's CDF")
    checks.independent_signs(np.asarray(k1, np.float64), cdf, 0.5, 0.5, "uniform(split(key)[0]) against the draw")


@pytest.mark.nightly  # another key implementation and dtype of the default threefry float32 tests
@pytest.mark.statistical(p=4e-7)
def test_rbg_keys_and_float64():
    # Keys of another implementation take their words from jax.random.bits; float64 draws take 64-bit words. Mean and
    # variance by Bernstein (bounded in [0, 1]) for each: 4 checks, <= 4e-7.
    checks = Checks()
    a, b, n = 0.8, 20.0, 50_000
    ref = stats.beta(a, b)
    keys = jax.random.split(jax.random.key(33, impl="rbg"), n)
    x = np.asarray(jax.jit(jax.vmap(lambda k: sample_beta(k, a, b)))(keys), np.float64)
    checks.bounded_moments(x, ref, 0.0, 1.0, "rbg keys")
    with jax.enable_x64(True):
        keys = jax.random.split(key(34), n)
        x = jax.jit(jax.vmap(lambda k: sample_beta(k, a, b, dtype=jnp.float64)))(keys)
        assert x.dtype == jnp.float64
        x = np.asarray(x)
        # 52-bit uniforms: float64 draws are not float32 values (a float32 stream would leave the low bits zero).
        assert np.mean(x != x.astype(np.float32)) > 0.99
    checks.bounded_moments(x, ref, 0.0, 1.0, "float64")


@functools.partial(jax.jit, static_argnames="trials")
def beta_draws(k, a, b, trials):
    return jax.vmap(lambda q: sample_beta(q, a, b, trials=trials))(jax.random.split(k, 50_000))


@pytest.mark.statistical(p=1e-6)
@pytest.mark.parametrize("trials", [4, 2])  # 2 trials: up to 9.4% of the rounds fail and are drawn again
@pytest.mark.parametrize("a, b", [(2.4, 24.0), (0.5, 0.5), (1.0, 1.0), (80.0, 1.0), (0.3, 3.0), (1.0, 0.11),
                                  (0.01, 0.11)])
def test_shared_sampler_is_exact(a, b, trials):
    # KS where float32 resolves the distribution, counts below the exact quantiles it resolves, mean and variance by
    # Bernstein (bounded in [0, 1]). At most 1 + 7 + 2 = 10 checks: false-failure probability <= 1e-6.
    x = np.asarray(beta_draws(key(37), jnp.float32(a), jnp.float32(b), trials), np.float64)
    assert np.all((x >= 0) & (x <= 1))
    ref, checks = stats.beta(a, b), Checks()
    if b >= 0.5:  # mass piled up just below 1 is rounded to 1.0 in float32, which a KS test would flag
        checks.ks(x, ref.cdf, f"Beta({a}, {b})")
    probs = [p for p in (1e-3, 0.02, 0.25, 0.5, 0.75, 0.98, 0.999) if 1e-30 < ref.ppf(p) < 1 - 1e-6]
    checks.below_quantiles(x, ref.ppf, probs, f"Beta({a}, {b})")
    checks.bounded_moments(x, ref, 0.0, 1.0, f"Beta({a}, {b})")


N_BITWISE = 1024
BITWISE_KEYS = jax.random.split(jax.random.key(38), N_BITWISE)
BITWISE_A = jax.random.uniform(jax.random.key(39), (N_BITWISE,), minval=0.005, maxval=6.0)
BITWISE_B = jax.random.uniform(jax.random.key(40), (N_BITWISE,), minval=0.005, maxval=6.0)
single_beta = jax.jit(sample_beta)


@functools.lru_cache(maxsize=None)
def single_draws(n: int) -> np.ndarray:
    """The first ``n`` draws, each from its own unbatched (jitted) call, as uint32 words."""
    return np.asarray([single_beta(BITWISE_KEYS[i], BITWISE_A[i], BITWISE_B[i]) for i in range(n)]).view(np.uint32)


@pytest.mark.parametrize("size", [1, 2, 3, 7, 60, 255, 1024])
def test_shared_sampler_batch_member_equals_single_call_bitwise(size):
    # Without the custom_vmap rule about 4% of the draws differed in the last bits (XLA CPU's scalar code contracts
    # other multiply-adds into FMAs than its vectorised kernels: module docstring). Batches of `size` members cover
    # at least 120 draws; each member must be its single call's value bit for bit, and so must an eager call.
    n = max(size, -(-120 // size) * size)
    batched = jax.jit(jax.vmap(sample_beta))
    got = np.concatenate([np.asarray(batched(BITWISE_KEYS[i:i + size], BITWISE_A[i:i + size], BITWISE_B[i:i + size]))
                          for i in range(0, n, size)]).view(np.uint32)
    np.testing.assert_array_equal(got, single_draws(n))
    if size == 1:
        eager = np.asarray([sample_beta(BITWISE_KEYS[i], BITWISE_A[i], BITWISE_B[i]) for i in range(8)])
        np.testing.assert_array_equal(eager.view(np.uint32), single_draws(8))


@pytest.mark.nightly  # by default: test_shared_sampler_batch_member_equals_single_call_bitwise
def test_shared_sampler_nested_and_partial_batches_equal_single_calls_bitwise():
    # Nested vmaps (both layouts), a shape or key shared by the batch (in_axes None: broadcast inside the rule), and
    # lax.map (the unbatched call inside a loop) give every member its single call's value bit for bit.
    n = 256
    want = single_draws(n)
    keys, a, b = BITWISE_KEYS[:n], BITWISE_A[:n], BITWISE_B[:n]
    grid = lambda x: x.reshape(8, 32)  # noqa: E731
    nested = jax.jit(jax.vmap(jax.vmap(sample_beta)))(grid(keys), grid(a), grid(b))
    np.testing.assert_array_equal(np.asarray(nested).reshape(-1).view(np.uint32), want)
    nested = jax.jit(jax.vmap(jax.vmap(sample_beta), in_axes=1))(grid(keys), grid(a), grid(b))
    np.testing.assert_array_equal(np.asarray(nested).T.reshape(-1).view(np.uint32), want)
    mapped = jax.jit(lambda k, a, b: jax.lax.map(lambda t: sample_beta(*t), (k, a, b)))(keys, a, b)
    np.testing.assert_array_equal(np.asarray(mapped).view(np.uint32), want)
    shared_shapes = jax.jit(jax.vmap(sample_beta, in_axes=(0, None, None)))(keys[:61], a[5], b[5])
    alone = np.asarray([single_beta(keys[i], a[5], b[5]) for i in range(61)])
    np.testing.assert_array_equal(np.asarray(shared_shapes).view(np.uint32), alone.view(np.uint32))
    shared_key = jax.jit(jax.vmap(sample_beta, in_axes=(None, 0, 0)))(keys[7], a[:61], b[:61])
    alone = np.asarray([single_beta(keys[7], a[i], b[i]) for i in range(61)])
    np.testing.assert_array_equal(np.asarray(shared_key).view(np.uint32), alone.view(np.uint32))


@pytest.mark.parametrize("size", [1, 3, 7, 60])
def test_step_batch_member_equals_single_step_bitwise(size):
    # The step itself (Beta rewards): a member of a vmap-ed batch of steps returns its single step's reward bit for
    # bit (tests/test_env.py checks whole trajectories at 1024 members).
    mdp = jaxmdp.make("FrozenLake", episodic=False, seed=0, size=3, make_reward_stochastic=True, p_frozen=0.9).strip()
    assert mdp.stochastic_rewards
    keys = jax.random.split(jax.random.key(41), size)
    states = jax.random.randint(jax.random.key(42), (size,), 0, mdp.n_states)
    actions = jax.random.randint(jax.random.key(43), (size,), 0, mdp.n_actions)

    def reward(k, s, a, mdp):
        return jaxmdp.step(k, jaxmdp.EnvState(state=s, h=jnp.zeros((), jnp.int32)), a, mdp)[2]

    batched = jax.jit(jax.vmap(reward, (0, 0, 0, None)))(keys, states, actions, mdp)
    single = jax.jit(reward)
    alone = np.asarray([single(keys[i], states[i], actions[i], mdp) for i in range(size)])
    np.testing.assert_array_equal(np.asarray(batched).view(np.uint32), alone.view(np.uint32))
    if size == 60:
        assert np.sum((alone > 0) & (alone < 1)) > 30  # mostly Beta draws, not point masses


# 2 trials: about 9% of the rounds fail, so rounds 1-3 decide many draws
@pytest.mark.nightly  # by default: the sampler's draws against single calls
@pytest.mark.parametrize("trials", [pytest.param(4, marks=pytest.mark.nightly), 2])
def test_rounds_before_the_loop_change_no_value(trials):
    # unrolled_rounds moves rounds out of the loop, never the round a member's value comes from: the same bits for
    # every member, batched (1024 members, 512 of them at the worst shapes a = b = 1) and alone.
    a = BITWISE_A.at[:512].set(1.0)
    b = BITWISE_B.at[:512].set(1.0)
    draws = {k: np.asarray(jax.jit(jax.vmap(functools.partial(sample_beta, trials=trials, unrolled_rounds=k)))(
        BITWISE_KEYS, a, b)).view(np.uint32) for k in (1, 2, 3)}
    np.testing.assert_array_equal(draws[2], draws[1])
    np.testing.assert_array_equal(draws[3], draws[1])
    fails = np.asarray(failed_rounds(BITWISE_KEYS, a, b, trials))
    if trials == 2:  # rounds 1, 2, ... decide these members' values (1 and 2 both fail for about 1 in 100)
        assert fails.sum() >= 40
    alone = jax.jit(functools.partial(sample_beta, trials=trials, unrolled_rounds=3))
    for i in np.flatnonzero(fails)[:8]:
        assert np.asarray(alone(BITWISE_KEYS[i], a[i], b[i])).view(np.uint32) == draws[1][i]
    with pytest.raises(ValueError, match="unrolled_rounds"):
        sample_beta(BITWISE_KEYS[0], 1.0, 1.0, unrolled_rounds=0)


def test_dummy_member_is_accepted_in_round_zero():
    # The member appended to unbatched calls (shape 1, fixed key words) finishes in round 0, so it never makes a
    # batch run a second round (module docstring, "Batches").
    one = jnp.float32(1.0)
    terms = (shape_terms(one), shape_terms(one))
    for impl, words in ((None, 2), ("threefry2x32", 2), ("rbg", 4)):
        data = jnp.arange(1, words + 1, dtype=jnp.uint32)
        k = data if impl is None else jax.random.wrap_key_data(data, impl=impl)
        assert float(beta_module._round(k, jnp.int32(0), beta_module.DEFAULT_TRIALS, jnp.stack([one, one]), terms)) >= 0


def test_edge_shapes_and_arguments():
    k = jax.random.key(35)
    x = np.asarray([float(sample_beta(k, a, b)) for a, b in
                    [(0.0, 2.0), (2.0, 0.0), (-1.0, 2.0), (np.nan, 1.0), (0.0, 0.0), (np.inf, 2.0)]])
    assert x[0] == 0.0 and x[1] == 1.0 and np.all(np.isnan(x[2:]))
    # Huge shapes: Beta(1e6, 1e6) has standard deviation 3.5e-4 around 1/2; tiny ones are 0 or 1 in float32.
    keys = jax.random.split(k, 200)
    big = np.asarray(jax.vmap(lambda q: sample_beta(q, 1e6, 1e6))(keys))
    assert np.all(np.abs(big - 0.5) < 0.003)  # 8.5 standard deviations
    tiny = np.asarray(jax.vmap(lambda q: sample_beta(q, 1e-20, 1e-20))(keys))
    assert set(np.unique(tiny)) <= {0.0, 1.0}
    with pytest.raises(ValueError, match="trials"):
        sample_beta(k, 1.0, 1.0, trials=1)
    with pytest.raises(ValueError, match="scalars"):
        sample_beta(k, jnp.ones(2), 1.0)


def reward_means(mdp: jaxmdp.MDP, k: jax.Array, n: int) -> np.ndarray:
    """``[S, A]`` averages of ``n`` rewards returned by ``jaxmdp.step`` from each state and action (h = 0)."""
    S, A = mdp.n_states, mdp.n_actions

    def one(k, s, a):
        state = jaxmdp.EnvState(state=s, h=jnp.zeros((), jnp.int32))
        return jaxmdp.step(k, state, a, mdp)[2]

    def pair(k, s, a):
        return jnp.mean(jax.vmap(one, (0, None, None))(jax.random.split(k, n), s, a))

    s, a = jnp.meshgrid(jnp.arange(S), jnp.arange(A), indexing="ij")
    keys = jax.random.split(k, S * A).reshape(S, A)
    return np.asarray(jax.jit(jax.vmap(jax.vmap(pair)))(keys, s, a), np.float64)


def reward_variances(mdp: jaxmdp.MDP) -> np.ndarray:
    """Exact ``[S, A]`` variance of the step's reward: the mixture over next states of Betas and point masses."""
    T = np.asarray(mdp.T, np.float64)
    m, c = np.asarray(mdp.reward_mean, np.float64), np.asarray(mdp.reward_conc, np.float64)
    beta_var = np.where(c > 0, m * (1 - m) / (c + 1), 0.0)
    second = (T * (beta_var + m * m)).sum(-1)
    R = (T * m).sum(-1)
    return np.maximum(second - R * R, 0.0)


STEP_MDPS = {
    "RiverSwim": dict(family="RiverSwim", episodic=True, size=5, make_reward_stochastic=True, p_lazy=0.1,
                      optimal_distribution=("beta", (0.01, 0.11)), sub_optimal_distribution=("beta", (2.4, 24.0)),
                      other_distribution=("beta", (2.4, 249.0))),
    "FrozenLake": dict(family="FrozenLake", episodic=False, size=3, make_reward_stochastic=True, p_frozen=0.9),
    "Taxi": dict(family="Taxi", episodic=False, size=4, length=1, width=1, space=1, n_locations=3,
                 make_reward_stochastic=True, p_rand=0.1),
}


@pytest.mark.statistical(p=1e-4)
@pytest.mark.parametrize("name", list(STEP_MDPS))
def test_step_rewards_have_the_mean_table_R(name):
    # For every (s, a), the mean of n rewards returned by jaxmdp.step from s (random next state, then its Beta or
    # point-mass reward) is checked against R[s, a] by Bernstein with the exact variance of the mixture (rewards in
    # [0, 1]). At most S A <= 1000 checks at 1e-7 each: false-failure probability <= 1e-4 per MDP.
    params = dict(STEP_MDPS[name])
    family = params.pop("family")
    mdp = jaxmdp.make(family, seed=0, **params).strip()
    assert mdp.stochastic_rewards and mdp.n_states * mdp.n_actions <= 1000
    n = 8000
    means = reward_means(mdp, key(36), n)
    R, var = np.asarray(mdp.R, np.float64), reward_variances(mdp)
    checks = Checks()
    for s in range(mdp.n_states):
        for a in range(mdp.n_actions):
            bound = max(1.0 - R[s, a], R[s, a])
            checks.bernstein_mean(means[s, a], n, R[s, a], var[s, a], bound, f"{name}: mean reward of (s={s}, a={a})")
    assert checks.false_failure_bound() <= 1e-4
