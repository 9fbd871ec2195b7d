"""The jaxlib CPU miscompilation guard (jaxmdp/jaxlib_workarounds/xla_cpu.py): the pattern that broke is computed
correctly; the guard applies exactly to the releases that miscompile it, logs when it applies and can be turned
off."""

import json
import logging
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np

import jaxmdp
from jaxmdp.jaxlib_workarounds import xla_cpu


def test_flag_is_set_for_affected_jaxlib():
    import jaxlib

    if xla_cpu.affected(jaxlib.__version__):
        assert xla_cpu.YNN_FLAG in os.environ.get("XLA_FLAGS", "")


def test_version_parsing_and_the_affected_range():
    assert xla_cpu._version_tuple("0.10.2") == (0, 10, 2)
    assert xla_cpu._version_tuple("0.11.0rc1") == (0, 11, 0)
    assert [xla_cpu.affected(v) for v in ("0.9.0", "0.10.1", "0.10.2", "0.11.0", "0.11.2", "0.12.0", "1.0.0")] == [
        False, False, True, True, True, False, False]


# The smallest program found that jaxlib 0.10.2 got wrong with YNNPACK fusions on (errors up to ~9 at h >= 14):
# per-row variances of gathered values, vmapped over time steps and over a batch, with unbatched indices. It sets
# `got` and its float64 value `want`.
_PROGRAM = textwrap.dedent(
    """
    import jax, jax.numpy as jnp, numpy as np
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
    want = (pp * (g - (pp * g).sum(-1, keepdims=True)) ** 2).sum(-1)
    """
)


def test_the_guarded_range_is_where_the_installed_jaxlib_miscompiles():
    # Keeps xla_cpu's version range honest: on a jaxlib the guard covers, the program must go wrong without the guard
    # (else the range is too wide: narrow it), and on any other it must be right (else widen it). The child process
    # does not import jaxmdp and leaves XLA_FLAGS alone, so it runs under the installed jaxlib's defaults.
    child = _PROGRAM + (
        "import json, jaxlib\n"
        "print(json.dumps(dict(jaxlib=jaxlib.__version__, error=float(np.abs(got - want).max()))))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    proc = subprocess.run([sys.executable, "-c", child], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    wrong = out["error"] > 1e-3
    assert wrong == xla_cpu.affected(out["jaxlib"]), out


def test_nested_vmap_variance_matches_numpy():
    # The same program in this process, where importing jaxmdp applied the guard.
    names: dict = {}
    exec(_PROGRAM, names)
    np.testing.assert_allclose(names["got"], names["want"], rtol=1e-5, atol=1e-5)


def test_fused_transform_value_norm_of_deterministic_mdp_is_zero():
    # The case that exposed the bug: p_rand = 0 leaves MiniGridEmpty deterministic, so the value norm is exactly 0.
    import hardness

    base = jaxmdp.make("MiniGridEmpty", episodic=True, seed=0, size=8, randomize_actions=False).strip()
    f = jax.jit(jax.vmap(lambda r: hardness.value_norm(jaxmdp.apply_p_rand(base, r)).value))
    out = np.asarray(f(jnp.asarray([0.0, 0.5], jnp.float32)))
    assert out[0] == 0.0
    np.testing.assert_allclose(out[1], float(hardness.value_norm(jaxmdp.apply_p_rand(base, 0.5)).value), rtol=1e-5)


def test_opt_out_and_log(monkeypatch, caplog):
    # No backend yet, as at import time; monkeypatch restores XLA_FLAGS and the opt-out variable afterwards.
    import jaxlib

    monkeypatch.setattr(xla_cpu, "_backend_exists", lambda: False)
    monkeypatch.setenv("XLA_FLAGS", "--xla_foo=1")
    monkeypatch.setenv(xla_cpu.OPT_OUT_VARIABLE, "1")
    assert not xla_cpu.disable_ynn_fusion()
    assert os.environ["XLA_FLAGS"] == "--xla_foo=1"
    monkeypatch.setenv(xla_cpu.OPT_OUT_VARIABLE, "0")  # "0" does not opt out
    with caplog.at_level(logging.INFO, logger="jaxmdp"):
        added = xla_cpu.disable_ynn_fusion()
    affected = xla_cpu.affected(jaxlib.__version__)
    assert added == affected
    if affected:
        assert os.environ["XLA_FLAGS"] == f"--xla_foo=1 {xla_cpu.YNN_FLAG}="
        assert xla_cpu.OPT_OUT_VARIABLE in caplog.text and "jax-ml/jax#39103" in caplog.text
        assert not xla_cpu.disable_ynn_fusion()  # already there: added once
