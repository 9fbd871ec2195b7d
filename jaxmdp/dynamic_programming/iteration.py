"""The one iterative loop of the value iterations: :func:`relative_value_iteration` iterates a Bellman backup given as
a function ``backup(u) -> Q[S, A]``.

The same loop solves an ordinary MDP (:func:`~jaxmdp.dynamic_programming.value_iteration`), UCRL2's extended MDP (the
backup maximises over a confidence set of kernels) and optimistic PSRL's extended MDP (the backup maximises over
sampled kernels). It is meant to be called inside the caller's ``jit``.

Average reward (``discount == 1``; Puterman 1994 §8.5, Jaksch et al. 2010 §3.1.2): with ``T u = max_a backup(u)`` and
``d = T u - u``, every iterate satisfies ``min_s d(s) <= rho* <= max_s d(s)`` and a policy greedy on ``backup(u)`` is
``span(d)``-optimal, so the loop stops when ``span(d) < tol``. Each step moves ``u <- u + tau d`` (``tau =
aperiodicity``), which is value iteration on the aperiodic transform ``P_tau = tau P + (1 - tau) I``: it has the same
gains and optimal policies, and makes the loop converge also when the optimal chains are periodic (deterministic
cycles, where plain value iteration oscillates for ever). ``u`` is shifted so that its minimum over real states is 0,
which keeps it bounded.

Discounted (``discount < 1``): plain value iteration, stopped when ``max_s |d(s)| < tol``; the caller's ``backup``
applies the discount.
"""

from __future__ import annotations

from collections.abc import Callable

import chex
import jax
import jax.numpy as jnp

from jaxmdp import struct

__all__ = ["PlanResult", "relative_value_iteration"]


class PlanResult(struct.PyTreeNode):
    """Result of :func:`relative_value_iteration`.

    ``Q = backup(u)`` at the returned ``u``; ``gain_lower``/``gain_upper`` are ``min``/``max`` of ``T u - u`` over
    the real states (bounds on the optimal gain when ``discount == 1``); ``converged`` tells whether the stopping
    rule was met within ``max_iter`` sweeps.
    """

    Q: jax.Array
    u: jax.Array
    gain_lower: jax.Array
    gain_upper: jax.Array
    iterations: jax.Array
    converged: jax.Array


def relative_value_iteration(
    backup: Callable[[jax.Array], jax.Array],
    u0: jax.Array,
    state_mask: jax.Array,
    action_mask: jax.Array,
    *,
    discount: float | jax.Array = 1.0,
    tol: float | jax.Array = 1e-3,
    max_iter: int = 100_000,
    aperiodicity: float | jax.Array = 0.5,
    active: bool | jax.Array = True,
) -> PlanResult:
    """Iterate ``u <- u + step * (max_a backup(u) - u)`` from ``u0`` until the stopping rule of the module
    docstring (``step`` is ``aperiodicity`` for average reward, 1 when discounted).

    Padded actions (``action_mask``) are excluded from the maximum; padded states (``state_mask``) from the stopping
    rule and the normalisation. ``discount`` may be traced (1 selects the average-reward rule, ``< 1`` the discounted
    one), so a hyperparameter grid can mix both. ``active = False`` skips the loop (the result is then meaningless):
    under ``vmap`` a batched ``while_loop`` runs until its last member stops, so members whose result will be
    discarded should not keep it going.
    """
    chex.assert_rank(u0, 1, custom_message="u0: values [S]")
    chex.assert_type(u0, float, custom_message="u0: values")
    chex.assert_shape(state_mask, u0.shape, custom_message="state_mask: [S] as u0")
    chex.assert_rank(action_mask, {1, 2}, custom_message="action_mask: [A] or [S, A]")
    chex.assert_rank(discount, 0, custom_message="discount: a scalar")
    dtype = u0.dtype
    average = jnp.asarray(discount) >= 1.0
    step = jnp.where(average, jnp.asarray(aperiodicity, dtype), jnp.asarray(1.0, dtype))
    inf = jnp.asarray(jnp.inf, dtype)

    def sweep(u):
        Q = backup(u)
        d = jnp.max(jnp.where(action_mask, Q, -inf), axis=-1) - u
        lo = jnp.min(jnp.where(state_mask, d, inf))
        hi = jnp.max(jnp.where(state_mask, d, -inf))
        err = jnp.where(average, hi - lo, jnp.maximum(hi, -lo))
        return Q, d, lo, hi, err

    def cond(c):
        *_, err, i = c
        return (err >= tol) & (i < max_iter) & active

    def body(c):
        u, *_, i = c
        Q, d, lo, hi, err = sweep(u)
        u_next = u + step * d
        u_next = jnp.where(average, u_next - jnp.min(jnp.where(state_mask, u_next, inf)), u_next)
        # Keep the ``u`` that produced ``Q`` when the rule is met, so the result is self-consistent.
        u_next = jnp.where(err < tol, u, u_next)
        return u_next, Q, lo, hi, err, i + 1

    S, A = u0.shape[0], action_mask.shape[-1]
    init = (u0, jnp.zeros((S, A), dtype), -inf, inf, inf, jnp.asarray(0, jnp.int32))
    u, Q, lo, hi, err, it = jax.lax.while_loop(cond, body, init)
    return PlanResult(Q=Q, u=u, gain_lower=lo, gain_upper=hi, iterations=it, converged=err < tol)


# ---------------------------------------------------------------------------------------------------------------
# Discounted
# ---------------------------------------------------------------------------------------------------------------
