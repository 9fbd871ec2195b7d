"""Jittable kernel transforms: random actions (``p_rand``) and lazy steps (``p_lazy``), paper App. C.

With ``r = p_rand``, ``l = p_lazy`` and ``A`` (valid) actions, Colosseum's families use (docs/families.md §1.3)

    P'(. | s, b) = l * delta_s + (1 - l) * [ (1 - r) P(. | s, b) + (r / A) sum_c P(. | s, c) ],

i.e. laziness outside the random-action mixture; :func:`apply_noise` composes the two transforms in that order.
The reward of every outcome is drawn from the distribution of the *chosen* action ``b`` and the *actual* next state,
``D(s, b, s')``, so the mean reward becomes ``R'[s, b] = sum_s' P'(s'|s, b) reward_mean[s, b, s']``. Families store
``reward_mean``/``reward_conc`` for every state a transform can add (``s`` itself and the successors of every
action), so a sweep over ``p_rand`` is one ``vmap`` over a single base MDP.

State order: the reference enumerates states depth-first over the *noisy* outcome lists, so an MDP built from scratch
with ``p_rand > 0`` can list its states in a different order from the base MDP. The transforms keep the base order;
the two MDPs are equal up to that relabelling (``jaxmdp.state_permutation`` finds it from the node labels).

Bad input: concrete values outside ``[0, 0.9999)`` raise ``ValueError``; traced values cannot raise, so an out-of-range
value makes every transition probability NaN (documented NaN policy) instead of returning a wrong kernel.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmdp.mdp import MDP

__all__ = ["apply_p_rand", "apply_p_lazy", "apply_noise", "MAX_NOISE_PROBABILITY"]

#: Upper bound (exclusive) of ``p_rand`` and ``p_lazy``, as in the reference.
MAX_NOISE_PROBABILITY = 0.9999


def _check_probability(name: str, p: float | jax.Array) -> None:
    try:
        value = float(p)
    except (TypeError, jax.errors.ConcretizationTypeError, jax.errors.TracerArrayConversionError):
        return  # traced: handled by the NaN policy
    if not 0.0 <= value < MAX_NOISE_PROBABILITY:
        raise ValueError(f"{name} must lie in [0, {MAX_NOISE_PROBABILITY}); got {value}")


def _nan_unless_valid(x: jax.Array, p: jax.Array) -> jax.Array:
    valid = (p >= 0) & (p < MAX_NOISE_PROBABILITY)
    return jnp.where(valid, x, jnp.nan)


def _with_kernel(mdp: MDP, T: jax.Array, succ: jax.Array, succ_p: jax.Array) -> MDP:
    R = jnp.sum(T * mdp.reward_mean, axis=-1)
    return mdp.replace(T=T, R=R, succ=succ, succ_p=succ_p)


def apply_p_rand(mdp: MDP, p_rand: float | jax.Array) -> MDP:
    """``P'(.|s,b) = (1 - r) P(.|s,b) + (r / A) sum_c P(.|s,c)`` over the valid actions (paper App. C).

    The successor lists grow to ``A * K`` entries (every action's list), so the result has the same shapes for every
    ``p_rand`` and a sweep vmaps over it.
    """
    _check_probability("p_rand", p_rand)
    r = jnp.asarray(p_rand, mdp.dtype)
    w = mdp.action_mask.astype(mdp.dtype)
    n_valid = jnp.sum(w)
    mix = jnp.einsum("c,sct->st", w, mdp.T) / n_valid
    T = (1.0 - r) * mdp.T + r * mix[:, None, :]
    T = _nan_unless_valid(T, r)
    S, A, K = mdp.succ.shape
    # Entry (c, k) of the new list of action b: the k-th successor of action c, weighted (1-r)[c == b] + r w_c / A.
    succ = jnp.broadcast_to(mdp.succ.reshape(S, 1, A * K), (S, A, A * K))
    weight = (1.0 - r) * jnp.eye(A, dtype=mdp.dtype) + r * (w / n_valid)[None, :]  # [b, c]
    succ_p = (weight[None, :, :, None] * mdp.succ_p[:, None, :, :]).reshape(S, A, A * K)
    return _with_kernel(mdp, T, succ, _nan_unless_valid(succ_p, r))


def apply_p_lazy(mdp: MDP, p_lazy: float | jax.Array) -> MDP:
    """``P'(.|s,a) = (1 - l) P(.|s,a) + l delta_s`` (paper App. C); the lists gain one self-loop entry."""
    _check_probability("p_lazy", p_lazy)
    l = jnp.asarray(p_lazy, mdp.dtype)  # noqa: E741
    S, A, K = mdp.succ.shape
    T = (1.0 - l) * mdp.T + l * jnp.eye(S, dtype=mdp.dtype)[:, None, :]
    T = _nan_unless_valid(T, l)
    self_idx = jnp.broadcast_to(jnp.arange(S, dtype=mdp.succ.dtype)[:, None, None], (S, A, 1))
    succ = jnp.concatenate([mdp.succ, self_idx], axis=-1)
    succ_p = jnp.concatenate([(1.0 - l) * mdp.succ_p, jnp.broadcast_to(l, (S, A, 1))], axis=-1)
    return _with_kernel(mdp, T, succ, _nan_unless_valid(succ_p, l))


def apply_noise(mdp: MDP, p_rand: float | jax.Array = 0.0, p_lazy: float | jax.Array = 0.0) -> MDP:
    """Random actions then laziness: ``apply_p_lazy(apply_p_rand(mdp, p_rand), p_lazy)`` (docs/families.md §1.3)."""
    return apply_p_lazy(apply_p_rand(mdp, p_rand), p_lazy)
