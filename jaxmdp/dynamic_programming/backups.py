"""The building blocks of dynamic programming: models, one Bellman backup, greedy and fixed policies, and the
:func:`compiled` wrapper that jits the routines with loops.

A model is either an :class:`~jaxmdp.MDP` (expectations then use its successor lists, ``O(S A K)`` per backup) or a
dense ``[S, A, S]`` kernel (used by agents that plan on sampled or estimated kernels). Rewards default to the MDP's
``R`` and can be overridden. Greedy policies break ties deterministically towards the lowest action index.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import chex
import jax
import jax.numpy as jnp

from jaxmdp._asserts import assert_model, assert_policy
from jaxmdp.mdp import MDP

__all__ = [
    "compiled",
    "expected_next_values",
    "q_values",
    "greedy",
    "greedy_actions",
    "uniform_policy",
    "policy_matrix",
    "policy_rewards",
]

Model = MDP | jax.Array


def compiled(*static_argnames: str) -> Callable[[Callable], Callable]:
    """Decorator: the routine jitted (``static_argnames`` static), its :class:`~jaxmdp.MDP` arguments stripped of their
    static metadata (:meth:`~jaxmdp.MDP.strip`) first.

    An eager call then compiles once per shape, and MDPs of one shape share the program whatever their labels. This
    is done because a routine with a loop called eagerly without ``jit`` compiles its loop again at every call (the
    loop body is a new closure each time), which dominates the cost of eager use (docs/performance.md, Compilation).
    Inside another ``jit`` the routine is inlined as before."""

    def wrap(fun: Callable) -> Callable:
        jitted = jax.jit(fun, static_argnames=static_argnames)
        strip = lambda x: x.strip() if isinstance(x, MDP) else x  # noqa: E731

        @functools.wraps(fun)
        def call(*args: Any, **kwargs: Any) -> Any:
            return jitted(*map(strip, args), **{k: strip(v) for k, v in kwargs.items()})

        call.jitted = jitted  # the jitted routine itself (e.g. ``.lower``)
        return call

    return wrap


# Up to this many actions greedy() unrolls its passes over the action axis (see there).
_UNROLLED_GREEDY_MAX_ACTIONS = 16


def _dense(model: Model) -> jax.Array:
    return model.T if isinstance(model, MDP) else model


def _rewards(model: Model, rewards: jax.Array | None) -> jax.Array:
    if rewards is not None:
        return rewards
    if isinstance(model, MDP):
        return model.R
    raise ValueError("rewards must be given when the model is a dense kernel")


def _action_mask(model: Model) -> jax.Array | None:
    return model.action_mask if isinstance(model, MDP) else None


def _masks(model: Model, R: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The real states and actions of ``model``: its masks, or all of them for a dense kernel."""
    if isinstance(model, MDP):
        return model.state_mask, model.action_mask
    return jnp.ones(R.shape[:1], bool), jnp.ones(R.shape[1:], bool)


def expected_next_values(model: Model, V: jax.Array) -> jax.Array:
    """``E[V(s') | s, a] = sum_s' P(s'|s,a) V(s')`` for every ``(s, a)``: an ``[S, A]`` array."""
    S, _ = assert_model(model)
    chex.assert_shape(V, (S,), custom_message="V: values [S]")
    if isinstance(model, MDP):
        return jnp.sum(model.succ_p * V[model.succ], axis=-1)
    return jnp.einsum("sat,t->sa", model, V)


def q_values(model: Model, V: jax.Array, gamma: float | jax.Array = 1.0, rewards: jax.Array | None = None) -> jax.Array:
    """One Bellman backup: ``Q = R + gamma * P V``."""
    assert_model(model, rewards)
    chex.assert_rank(gamma, 0, custom_message="gamma: a scalar discount")
    return _rewards(model, rewards) + gamma * expected_next_values(model, V)


def greedy_actions(Q: jax.Array, action_mask: jax.Array | None = None, atol: float = 0.0) -> jax.Array:
    """The greedy action of every row of ``Q[..., A]`` as an ``int32`` index: the lowest index within ``atol`` of the
    row's maximum, padded actions (``action_mask``) excluded. :func:`greedy` is its one-hot form."""
    if action_mask is not None:
        chex.assert_shape(action_mask, (..., Q.shape[-1]), custom_message="action_mask: [..., A] as Q")
    if action_mask is not None:
        Q = jnp.where(action_mask, Q, -jnp.inf)
    A = Q.shape[-1]
    if A > _UNROLLED_GREEDY_MAX_ACTIONS:
        best = jnp.max(Q, axis=-1, keepdims=True)
        return jnp.argmax(Q >= best - atol, axis=-1).astype(jnp.int32)
    # Few actions: elementwise passes over the action axis. XLA runs the variadic argmax reduction several times
    # slower on CPU, and a lockstep run evaluates a greedy policy for every member at every log.
    best = Q[..., 0]
    for a in range(1, A):
        best = jnp.maximum(best, Q[..., a])
    index = jnp.zeros(Q.shape[:-1], jnp.int32)
    for a in reversed(range(A)):
        index = jnp.where(Q[..., a] >= best - atol, a, index)
    return index


def greedy(Q: jax.Array, action_mask: jax.Array | None = None, atol: float = 0.0) -> jax.Array:
    """One-hot greedy policy of ``Q[..., A]``.

    Actions within ``atol`` of the maximum count as tied and the lowest index wins. ``action_mask`` excludes padded
    actions.
    """
    return jax.nn.one_hot(greedy_actions(Q, action_mask, atol), Q.shape[-1], dtype=Q.dtype)


def uniform_policy(model: Model, shape: tuple[int, ...] = ()) -> jax.Array:
    """The uniformly random policy ``pi(a|s) = 1/|A|`` over the valid actions, shape ``[*shape, S, A]``."""
    assert_model(model)
    T = _dense(model)
    S, A = T.shape[0], T.shape[1]
    mask = _action_mask(model)
    w = jnp.ones((A,), T.dtype) if mask is None else mask.astype(T.dtype)
    return jnp.broadcast_to(w / jnp.sum(w), (*shape, S, A))


def policy_matrix(model: Model, pi: jax.Array) -> jax.Array:
    """State-to-state kernel ``P_pi[s, s'] = sum_a pi(a|s) P(s'|s,a)`` of a stationary policy ``pi[S, A]``."""
    assert_policy(pi, *assert_model(model))
    return jnp.einsum("sa,sat->st", pi, _dense(model))


def policy_rewards(model: Model, pi: jax.Array, rewards: jax.Array | None = None) -> jax.Array:
    """Expected one-step reward ``r_pi(s) = sum_a pi(a|s) R(s,a)`` (``pi[S, A]``, or ``[H, S, A]`` for each step)."""
    assert_policy(pi, *assert_model(model, rewards), time_indexed=True)
    return jnp.sum(pi * _rewards(model, rewards), axis=-1)
