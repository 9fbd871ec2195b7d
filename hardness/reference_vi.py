"""The reference's discounted value iteration, reproduced for the ``variant="colosseum"`` measures (docs/measures.md
§1.1).

Start from ``V = 0``; a sweep is either *Gauss-Seidel* (states in index order, each using the values already updated
in the same sweep) or *Jacobi* (synchronous); stop after the first sweep with ``max_s |V_before - V| < eps`` and
return that sweep's ``Q`` and ``V``. The reference takes the Jacobi path when the dense kernel has more than 270 000
entries (``S * A * S``) and fewer than 20 % of them are non-zero, Gauss-Seidel otherwise. Both stop short of the fixed
point (``|V - V*| <= eps * gamma / (1 - gamma)``), and the measures built on them inherit that error: this module
exists only for parity with the reference's numbers. The exact solvers are in :mod:`jaxmdp.dynamic_programming`.

Everything works on successor lists (``succ[S, A, K]``, ``succ_p[S, A, K]``) so that it serves both an MDP and the
continuous form of an episodic one, and it vmaps over stacked batches (the path is chosen per member).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["DENSE_SIZE_LIMIT", "SPARSE_FRACTION", "uses_jacobi", "reference_value_iteration"]

#: The reference switches to its sparse (Jacobi) solver above this many dense kernel entries ...
DENSE_SIZE_LIMIT = 270_000
#: ... when fewer than this fraction of them are non-zero.
SPARSE_FRACTION = 0.2


def uses_jacobi(succ_p: jax.Array, row_mask: jax.Array, action_mask: jax.Array) -> jax.Array:
    """Whether the reference would take its Jacobi path for this (unpadded) kernel: ``S A S > 270 000`` and
    ``nnz / (S A S) < 0.2`` (successor lists hold distinct states, so ``nnz`` counts their positive entries)."""
    valid = row_mask[:, None, None] & action_mask[None, :, None]
    nnz = jnp.sum((succ_p > 0) & valid).astype(jnp.float32)
    n = jnp.sum(row_mask).astype(jnp.float32)
    size = n * jnp.sum(action_mask).astype(jnp.float32) * n
    return (size > DENSE_SIZE_LIMIT) & (nnz < SPARSE_FRACTION * size)


def reference_value_iteration(
    succ: jax.Array,
    succ_p: jax.Array,
    R: jax.Array,
    gamma: float | jax.Array,
    *,
    jacobi: jax.Array,
    row_mask: jax.Array,
    eps: float = 1e-3,
    max_iter: int = 1_000_000,
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """``(Q, V, converged)`` of the reference's value iteration (module docstring); ``jacobi`` picks the path.

    Gauss-Seidel visits only the real rows (``row_mask``; padded rows are absorbing with zero reward and stay 0).
    """
    S = R.shape[0]

    def backup_row(V, s):
        return R[s] + gamma * jnp.sum(succ_p[s] * V[succ[s]], axis=-1)

    def gauss_seidel(V):
        # A static trip count keeps the loop index unbatched under vmap (in-place row updates); padded rows and
        # Jacobi members are left alone.
        def body(s, c):
            V, Q = c
            q = backup_row(V, s)
            skip = jacobi | ~row_mask[s]
            return V.at[s].set(jnp.where(skip, V[s], jnp.max(q))), Q.at[s].set(jnp.where(skip, Q[s], q))

        return jax.lax.fori_loop(0, S, body, (V, jnp.zeros_like(R)))

    def jacobi_sweep(V):
        Q = R + gamma * jnp.sum(succ_p * V[succ], axis=-1)
        return jnp.max(Q, -1), Q

    def sweep(V):
        # cond runs one branch for a single MDP; under vmap it becomes a select over both.
        return jax.lax.cond(jacobi, jacobi_sweep, gauss_seidel, V)

    def cond(c):
        _, _, diff, i = c
        return (diff >= eps) & (i < max_iter)

    def body(c):
        V, _, _, i = c
        V_new, Q = sweep(V)
        return V_new, Q, jnp.max(jnp.abs(V_new - V)), i + 1

    init = (jnp.zeros((S,), R.dtype), jnp.zeros_like(R), jnp.asarray(jnp.inf, R.dtype), jnp.asarray(0))
    V, Q, diff, _ = jax.lax.while_loop(cond, body, init)
    return Q, V, diff < eps
