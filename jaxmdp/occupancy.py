"""State-visitation distributions of a policy: the Cesàro limit of its chain (re-exported from
:func:`jaxmdp.dynamic_programming.cesaro_limit`), and its long-run, discounted or in-episode state distribution from
``P0``. Used by the hardness measures of ``hardness.mismatch`` and ``hardness.mixing`` and by the pictures of
:mod:`jaxmdp.plotting`. Jittable; vmaps over a stacked batch.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmdp import dynamic_programming as dp
from jaxmdp.dynamic_programming import cesaro_limit
from jaxmdp.jaxlib_workarounds.linalg import solve as linear_solve
from jaxmdp.mdp import MDP

__all__ = ["cesaro_limit", "state_distribution"]


def state_distribution(mdp: MDP, policy: jax.Array, gamma: float | jax.Array | None = None) -> jax.Array:
    """The state-visitation distribution ``d^pi[S]`` of ``policy`` from ``P0``.

    * continuous MDP, ``gamma=None``: the long-run distribution ``d^T = P0^T P*_pi`` (the stationary distribution of
      a unichain policy);
    * continuous MDP, ``gamma`` in ``(0, 1)``: the discounted visitation
      ``d^T = (1 - gamma) P0^T (I - gamma P_pi)^-1 = (1 - gamma) sum_t gamma^t P0^T P_pi^t``;
    * episodic MDP (``gamma`` ignored): the in-episode average ``(1/H) sum_{h<H} Pr(s_h = . | s_0 ~ P0, pi)`` with
      ``pi`` stationary ``[S, A]`` or time-indexed ``[H, S, A]`` (``H`` the MDP's traced ``horizon``).
    """
    if mdp.episodic:
        pis = jnp.broadcast_to(policy, (mdp.H, *policy.shape[-2:])) if policy.ndim == 2 else policy

        def step(d, x):
            h, pi_h = x
            return d @ dp.policy_matrix(mdp, pi_h), jnp.where(h < mdp.horizon, d, 0.0)

        _, ds = jax.lax.scan(step, mdp.P0, (jnp.arange(mdp.H), pis))
        return jnp.sum(ds, axis=0) / mdp.horizon.astype(mdp.dtype)
    P = dp.policy_matrix(mdp, policy)
    if gamma is None:
        return mdp.P0 @ cesaro_limit(P)
    eye = jnp.eye(P.shape[0], dtype=P.dtype)
    return (1.0 - gamma) * linear_solve((eye - gamma * P).T, mdp.P0)
