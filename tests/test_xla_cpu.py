"""The jaxlib 0.10.2 CPU miscompilation guard (jaxmdp/jaxlib_workarounds/xla_cpu.py): the pattern that broke is computed correctly."""

import os

import jax
import jax.numpy as jnp
import numpy as np

import jaxmdp
from jaxmdp.jaxlib_workarounds import xla_cpu


def test_flag_is_set_for_affected_jaxlib():
    import jaxlib

    if xla_cpu._version_tuple(jaxlib.__version__) >= xla_cpu._FIRST_AFFECTED:
        assert xla_cpu.YNN_FLAG in os.environ.get("XLA_FLAGS", "")


def test_version_parsing():
    assert xla_cpu._version_tuple("0.10.2") == (0, 10, 2)
    assert xla_cpu._version_tuple("0.11.0rc1") == (0, 11, 0)
    assert xla_cpu._version_tuple("0.10.1") < xla_cpu._FIRST_AFFECTED


def test_nested_vmap_variance_matches_numpy():
    # The smallest program found that jaxlib 0.10.2 got wrong with YNNPACK fusions on (errors up to ~9 at h >= 14):
    # per-row variances of gathered values, vmapped over time steps and over a batch, with unbatched indices.
    rng = np.random.default_rng(0)
    S, A, K, B, H = 256, 3, 3, 2, 20
    succ = rng.integers(0, S, size=(S, A, K)).astype(np.int32)
    W = rng.random((B, H, S)).astype(np.float32)
    p = rng.random((B, S, A, K)).astype(np.float32)

    def variance(sp, w):
        E = jnp.sum(sp * w[succ], -1)
        return jnp.sum(sp * (w[succ] - E[..., None]) ** 2, -1)

    f = jax.jit(lambda Wb, pb: jax.vmap(lambda Wh, sp: jax.vmap(lambda w: variance(sp, w))(Wh))(Wb, pb))
    got = np.asarray(f(W, p))
    g = W[:, :, succ].astype(np.float64)  # [B, H, S, A, K]
    pp = p[:, None].astype(np.float64)
    E = (pp * g).sum(-1, keepdims=True)
    want = (pp * (g - E) ** 2).sum(-1)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


def test_fused_transform_value_norm_of_deterministic_mdp_is_zero():
    # The case that exposed the bug: p_rand = 0 leaves MiniGridEmpty deterministic, so the value norm is exactly 0.
    import hardness

    base = jaxmdp.make("MiniGridEmpty", episodic=True, seed=0, size=8, randomize_actions=False).strip()
    f = jax.jit(jax.vmap(lambda r: hardness.value_norm(jaxmdp.apply_p_rand(base, r)).value))
    out = np.asarray(f(jnp.asarray([0.0, 0.5], jnp.float32)))
    assert out[0] == 0.0
    np.testing.assert_allclose(out[1], float(hardness.value_norm(jaxmdp.apply_p_rand(base, 0.5)).value), rtol=1e-5)
