"""jaxmdp.jaxlib_workarounds.linalg.solve and .one_at_a_time (here around jnp.linalg.qr): jnp.linalg's numbers
under any vmap, and no deadlock of jaxlib 0.10.2's CPU pool.

The deadlock check runs in a subprocess with ``NPROC=2`` (XLA's intra-op pool of two threads, whatever the machine)
and a program with eight independent batched solves in a loop. With ``vmap(jnp.linalg.solve)`` in place of
:func:`jaxmdp.jaxlib_workarounds.linalg.solve`, this program and two like it hung in each of 9 tries (1 and 2 host
devices, jaxlib 0.10.2), so a hang of the subprocess is the regression test: detected by progress (no CPU time and no
output for a minute, see tests/progress_run.py), not by a wall-clock limit that a loaded machine could exceed. The
QR's deadlock is rarer (a program with eight independent ``vmap(jnp.linalg.qr)`` of 16 matrices 64 x 64 in a loop of
100 steps hung on its first try, another of 30 steps did not in 4), so its regression test is structural: under
``vmap`` every LAPACK call of ``one_at_a_time(jnp.linalg.qr)`` gets one matrix, which jaxlib runs on the calling
thread.
"""

from __future__ import annotations

import os
import re
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import REPO
from progress_run import run_with_progress
from jaxmdp.jaxlib_workarounds.linalg import one_at_a_time, solve


def _systems(key, shape, S):
    ka, kb = jax.random.split(key)
    a = 2.0 * jnp.eye(S) + 0.3 * jax.random.uniform(ka, (*shape, S, S))
    b = jax.random.uniform(kb, (*shape, S))
    return a, b


def test_unbatched_is_jnp_solve_and_solves_the_system():
    a, b = _systems(jax.random.key(0), (), 6)
    x = jax.jit(solve)(a, b)
    np.testing.assert_array_equal(np.asarray(x), np.asarray(jax.jit(jnp.linalg.solve)(a, b)))
    np.testing.assert_allclose(np.asarray(a, np.float64) @ np.asarray(x, np.float64), np.asarray(b), atol=2e-6)


def test_vmap_equals_batched_lapack_bitwise():
    a, b = _systems(jax.random.key(1), (7,), 9)
    ours = jax.jit(jax.vmap(solve))(a, b)
    lapack = jax.jit(jax.vmap(jnp.linalg.solve))(a, b)
    np.testing.assert_array_equal(np.asarray(ours), np.asarray(lapack))


def test_nested_vmap_and_unbatched_operands():
    a, b = _systems(jax.random.key(2), (3, 4), 5)
    a64, b64 = np.asarray(a, np.float64), np.asarray(b, np.float64)
    tol = dict(rtol=2e-5, atol=2e-6)
    expected = np.linalg.solve(a64, b64[..., None])[..., 0]
    np.testing.assert_allclose(np.asarray(jax.jit(jax.vmap(jax.vmap(solve)))(a, b)), expected, **tol)
    # One matrix with many right-hand sides, and many matrices with one right-hand side.
    one_matrix = jax.vmap(solve, in_axes=(None, 0))(a[0, 0], b[0])
    np.testing.assert_allclose(np.asarray(one_matrix), np.linalg.solve(a64[0, 0], b64[0].T).T, **tol)
    one_rhs = jax.vmap(solve, in_axes=(0, None))(a[0], b[0, 0])
    expected_one_rhs = np.linalg.solve(a64[0], np.broadcast_to(b64[0, 0], (4, 5))[..., None])[..., 0]
    np.testing.assert_allclose(np.asarray(one_rhs), expected_one_rhs, **tol)


DEADLOCK_PROGRAM = textwrap.dedent(
    """
    import jax, jax.numpy as jnp
    from jaxmdp.jaxlib_workarounds.linalg import solve

    S, B, K = 55, 10, 8
    a = 2.0 * jnp.eye(S) + 0.01 * jax.random.normal(jax.random.key(0), (B, S, S))
    b = jnp.ones((B, S))

    def step(i, x):
        # K independent batched solves: XLA runs them concurrently on its intra-op pool.
        return sum(jax.vmap(solve)(a + k, x) for k in range(K)) / (2.0 * K) + b

    out = jax.jit(lambda x: jax.lax.fori_loop(0, 100, step, x))(b)
    print("finite", bool(jnp.all(jnp.isfinite(out))))
    """
)


def test_many_concurrent_batched_solves_do_not_deadlock_the_cpu_pool():
    env = {**os.environ, "NPROC": "2", "JAX_PLATFORMS": "cpu", "PYTHONPATH": str(REPO)}
    env.pop("XLA_FLAGS", None)
    done = run_with_progress([sys.executable, "-c", DEADLOCK_PROGRAM], env=env, cwd=REPO, stall_s=60, limit_s=600)
    if done.hung:
        pytest.fail("batched solves deadlocked XLA's CPU thread pool (jaxmdp.jaxlib_workarounds.linalg.solve must map "
                    "one system at a time)")
    assert not done.over_limit, "the program still ran after 600 s"
    assert done.returncode == 0, done.stderr[-2000:]
    assert "finite True" in done.stdout


# ---------------------------------------------------------------------------------------------------------------
# one_at_a_time, on a function with two outputs
# ---------------------------------------------------------------------------------------------------------------


@one_at_a_time
def qr(a):
    return jnp.linalg.qr(a)


@pytest.mark.parametrize("shape", [(6, 4), (4, 6), (5, 5)])
def test_qr_is_jnp_qr_and_decomposes_the_matrix(shape):
    a = jax.random.normal(jax.random.key(3), shape)
    q, r = jax.jit(qr)(a)
    q_ref, r_ref = jax.jit(jnp.linalg.qr)(a)
    np.testing.assert_array_equal(np.asarray(q), np.asarray(q_ref))
    np.testing.assert_array_equal(np.asarray(r), np.asarray(r_ref))
    k = min(shape)
    q64, r64 = np.asarray(q, np.float64), np.asarray(r, np.float64)
    assert q.shape == (shape[0], k) and r.shape == (k, shape[1])
    np.testing.assert_allclose(q64.T @ q64, np.eye(k), atol=1e-6)
    np.testing.assert_allclose(q64 @ r64, np.asarray(a), atol=1e-5)
    np.testing.assert_array_equal(np.tril(r64, -1), 0.0)


def test_qr_under_nested_vmap_equals_batched_lapack_bitwise():
    a = jax.random.normal(jax.random.key(4), (3, 5, 7, 4))
    ours = jax.jit(jax.vmap(jax.vmap(qr)))(a)
    lapack = jax.jit(jax.vmap(jax.vmap(jnp.linalg.qr)))(a)
    for x, y in zip(ours, lapack, strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def _lapack_operands(fn, *args) -> list[tuple[str, str]]:
    """``(target, operand type)`` of every LAPACK custom call in the lowered program."""
    text = jax.jit(fn).lower(*args).as_text()
    return re.findall(r"stablehlo.custom_call @(lapack_\w+)\(%[^)]*\).*?: \((tensor<[^>]*>)", text)


def test_qr_under_vmap_hands_lapack_one_matrix_per_call():
    a = jnp.zeros((3, 5, 6, 4))
    ours = _lapack_operands(jax.vmap(jax.vmap(qr)), a)
    assert {t for t, _ in ours} == {"lapack_sgeqrf_ffi", "lapack_sorgqr_ffi"}
    assert {x for _, x in ours} == {"tensor<6x4xf32>"}
    # The check can fail: the batched decomposition hands LAPACK all 15 matrices at once.
    assert {x for _, x in _lapack_operands(jax.vmap(jax.vmap(jnp.linalg.qr)), a)} == {"tensor<3x5x6x4xf32>"}
