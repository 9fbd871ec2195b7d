"""Finite-horizon dynamic programming (paper §2.1): backward induction and exact policy evaluation.

With horizon ``H``: ``V_H = 0``, ``Q_h = R + P V_{h+1}``, ``V_h = max_a Q_h`` for ``h = H-1..0``; arrays carry ``H``
time rows for ``Q`` and ``H + 1`` for ``V`` (row ``H`` is zero). A traced ``horizon <= H`` makes the steps ``h >=
horizon`` worth zero, so stacked MDPs of different horizons share one program. The ``*_start_values`` routines return
``V_0`` alone (what an episodic regret indicator needs) and the ``*_deterministic_*`` ones read only the chosen
action's successor list.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import chex
import jax
import jax.numpy as jnp

from jaxmdp._asserts import assert_mdp, assert_model, assert_policy
from jaxmdp.dynamic_programming.backups import Model, _rewards, compiled, q_values
from jaxmdp.mdp import MDP

__all__ = [
    "finite_horizon_value_iteration",
    "finite_horizon_policy_evaluation",
    "finite_horizon_start_values",
    "finite_horizon_deterministic_evaluation",
    "finite_horizon_deterministic_start_values",
    "successor_rows",
]


def _horizon_args(model: Model, H: int | None, horizon: Any) -> tuple[int, jax.Array]:
    if H is None:
        if not isinstance(model, MDP) or model.H is None:
            raise ValueError("H must be given for a continuous MDP or a dense kernel")
        H = model.H
    if horizon is None:
        horizon = model.horizon if isinstance(model, MDP) and model.H is not None else H
    chex.assert_rank(horizon, 0, custom_message="horizon: a scalar episode length")
    return H, jnp.asarray(horizon)


def _assert_time_indexed(x: jax.Array, H: int, name: str) -> None:
    """A time-indexed ``x`` (rank 3 for a policy, 2 for actions) has at least ``H`` time rows (``x[:H]`` is read)."""
    if x.ndim == (3 if name == "pi" else 2):
        chex.assert_axis_dimension_gteq(x, 0, H, custom_message=f"{name}: at least H = {H} time steps")


@compiled("H")
def finite_horizon_value_iteration(
    model: Model, rewards: jax.Array | None = None, H: int | None = None, horizon: Any = None
) -> tuple[jax.Array, jax.Array]:
    """Exact backward induction on a stationary model.

    Returns ``Q[H, S, A]`` and ``V[H + 1, S]`` with ``V[H] = 0``; time steps ``h >= horizon`` are worth zero.
    """
    assert_model(model, rewards)
    R = _rewards(model, rewards)
    H, horizon = _horizon_args(model, H, horizon)

    def step(V_next, h):
        Q = jnp.where(h < horizon, q_values(model, V_next, 1.0, R), 0.0)
        V = jnp.max(Q, axis=-1)
        return V, (Q, V)

    V_H = jnp.zeros(R.shape[:1], R.dtype)
    _, (Q, V) = jax.lax.scan(step, V_H, jnp.arange(H), reverse=True)
    return Q, jnp.concatenate([V, V_H[None]], axis=0)


def _backward(step: Callable, V_H: jax.Array, xs: Any, all_steps: bool) -> Any:
    """Backward induction ``V_h = step(V_{h+1}, xs[h])`` from ``V_H``: ``(V[H + 1, S], ys)`` with ``ys`` the stacked
    extra outputs of ``step`` when ``all_steps``, else ``V_0`` alone. Without the stacked outputs the scan carries
    ``V`` only, because the runner's indicators need ``V_0`` and nothing else and writing every step's ``V`` (and
    ``Q``) is a large part of an episodic evaluation's cost (docs/performance.md, Episodic evaluation)."""
    if all_steps:

        def keep(V_next, x):
            V, y = step(V_next, x)
            return V, (V, y)

        _, (V, ys) = jax.lax.scan(keep, V_H, xs, reverse=True)
        return jnp.concatenate([V, V_H[None]], axis=0), ys
    V_0, _ = jax.lax.scan(lambda V, x: (step(V, x)[0], None), V_H, xs, reverse=True)
    return V_0


def _policy_backup(model: Model, R: jax.Array, horizon: jax.Array) -> Callable:
    """One backward step of policy evaluation: ``(V_{h+1}, (h, pi_h)) -> (V_h, Q_h)``."""

    def step(V_next, x):
        h, pi_h = x
        Q = jnp.where(h < horizon, q_values(model, V_next, 1.0, R), 0.0)
        return jnp.sum(pi_h * Q, axis=-1), Q

    return step


def _time_indexed(pi: jax.Array, H: int, shape: tuple[int, ...]) -> jax.Array:
    return jnp.broadcast_to(pi, (H, *shape)) if pi.ndim == 2 else pi[:H]


@compiled("H")
def finite_horizon_policy_evaluation(
    model: Model, pi: jax.Array, rewards: jax.Array | None = None, H: int | None = None, horizon: Any = None
) -> tuple[jax.Array, jax.Array]:
    """Exact finite-horizon evaluation of ``pi[H, S, A]`` (time-indexed) or ``pi[S, A]`` (stationary).

    Returns ``Q[H, S, A]`` and ``V[H + 1, S]`` with ``V_h = sum_a pi_h(a|s) Q_h(s, a)``.
    """
    assert_policy(pi, *assert_model(model, rewards), time_indexed=True)
    R = _rewards(model, rewards)
    H, horizon = _horizon_args(model, H, horizon)
    _assert_time_indexed(pi, H, "pi")
    V_H = jnp.zeros(R.shape[:1], R.dtype)
    V, Q = _backward(_policy_backup(model, R, horizon), V_H, (jnp.arange(H), _time_indexed(pi, H, R.shape)), True)
    return Q, V


@compiled("H")
def finite_horizon_start_values(
    model: Model, pi: jax.Array, rewards: jax.Array | None = None, H: int | None = None, horizon: Any = None
) -> jax.Array:
    """``V_0[S]`` of :func:`finite_horizon_policy_evaluation` (the same numbers), without keeping the other steps'
    ``Q`` and ``V``: what an episodic regret indicator needs (``sum_s P0(s) V_0(s)``, paper App. A.1)."""
    assert_policy(pi, *assert_model(model, rewards), time_indexed=True)
    R = _rewards(model, rewards)
    H, horizon = _horizon_args(model, H, horizon)
    _assert_time_indexed(pi, H, "pi")
    V_H = jnp.zeros(R.shape[:1], R.dtype)
    return _backward(_policy_backup(model, R, horizon), V_H, (jnp.arange(H), _time_indexed(pi, H, R.shape)), False)


def successor_rows(mdp: MDP) -> jax.Array:
    """The successor lists packed one row per ``(s, a)``: ``[..., S, A, 2 K + 1]`` holding ``[p_1..p_K, R(s, a),
    succ_1..succ_K]``, the successor indices bit-cast to the reward dtype (exactly); of an MDP, or of a stacked one
    (a leading MDP axis). What :func:`finite_horizon_deterministic_evaluation` reads: one gather of the chosen rows
    per step instead of three, which makes the evaluation markedly faster with the same numbers (docs/performance.md,
    Episodic evaluation)."""
    chex.assert_equal_shape([mdp.succ, mdp.succ_p], custom_message="mdp: succ and succ_p [..., S, A, K]")
    chex.assert_equal_shape_prefix([mdp.R, mdp.succ], mdp.R.ndim, custom_message="mdp: R [..., S, A] as succ")
    dtype = mdp.R.dtype
    succ = jax.lax.bitcast_convert_type(mdp.succ.astype(_same_width_int(dtype)), dtype)
    return jnp.concatenate([mdp.succ_p.astype(dtype), mdp.R[..., None], succ], axis=-1)


def _same_width_int(dtype: Any) -> Any:
    """The integer dtype that a float ``dtype`` bit-casts to (the successor columns of :func:`successor_rows`)."""
    return {4: jnp.int32, 8: jnp.int64}[jnp.dtype(dtype).itemsize]


def _assert_actions(mdp: MDP, actions: jax.Array) -> None:
    """``mdp`` is one episodic MDP and ``actions`` its time-indexed action indices ``[H, S]``."""
    S, _ = assert_mdp(mdp)
    chex.assert_shape(actions, (None, S), custom_message="actions: action indices [H, S]")
    chex.assert_type(actions, int, custom_message="actions: action indices")
    if mdp.H is not None:
        _assert_time_indexed(actions, mdp.H, "actions")


def _deterministic_backup(mdp: MDP, rows: jax.Array | None, member: jax.Array | None) -> Callable:
    """One backward step of :func:`finite_horizon_deterministic_evaluation`: ``(V_{h+1}, (h, a_h)) -> (V_h, ())``,
    reading ``rows[member]`` (a stacked MDP's :func:`successor_rows`) when given, else the MDP's own."""
    _, horizon = _horizon_args(mdp, None, None)
    S, K = mdp.n_states, mdp.succ.shape[-1]
    states = jnp.arange(S)
    as_int = _same_width_int(mdp.R.dtype)
    table = successor_rows(mdp) if rows is None else rows
    index = (states,) if rows is None else (member, states)

    def step(V_next, x):
        h, a_h = x
        rows_h = table[(*index, a_h)]
        nxt = jax.lax.bitcast_convert_type(rows_h[:, K + 1:], as_int).reshape(-1)
        expected = jnp.sum(rows_h[:, :K] * jnp.take(V_next, nxt, mode="clip").reshape(S, K), axis=-1)
        return jnp.where(h < horizon, rows_h[:, K] + 1.0 * expected, 0.0), ()

    return step


@compiled()
def finite_horizon_deterministic_evaluation(mdp: MDP, actions: jax.Array) -> jax.Array:
    """``V[H + 1, S]`` of the deterministic time-indexed policy ``actions[H, S]`` (action indices) on an MDP's
    successor lists: ``V_h(s) = R(s, a_h(s)) + sum_k p_k V_{h+1}(s'_k)`` over the successors of ``(s, a_h(s))``,
    ``V_h = 0`` for ``h >= horizon``.

    The same numbers as :func:`finite_horizon_policy_evaluation` of the one-hot policy (``V_h = sum_a pi_h(a|s)
    Q_h(s, a)`` adds exact zeros to the chosen action's ``Q``), at ``O(H S K)`` instead of ``O(H S A K)``: only the
    chosen action's successor list is read.
    """
    _assert_actions(mdp, actions)
    V_H = jnp.zeros((mdp.n_states,), mdp.R.dtype)
    return _backward(_deterministic_backup(mdp, None, None), V_H, (jnp.arange(mdp.H), actions[: mdp.H]), True)[0]


@compiled()
def finite_horizon_deterministic_start_values(
    mdp: MDP, actions: jax.Array, rows: jax.Array | None = None, member: jax.Array | None = None
) -> jax.Array:
    """``V_0[S]`` of :func:`finite_horizon_deterministic_evaluation` (the same numbers), carrying ``V`` alone through
    the backward pass: the episodic indicators' evaluation of an agent's greedy actions (paper App. A.1).

    ``rows`` and ``member``: the :func:`successor_rows` of a stacked MDP and this MDP's index in the stack (``mdp``
    then supplies the horizon and sizes). Under ``vmap`` over the members of a stacked grid, every gather then reads
    the unbatched stack by ``(member, s, a)``. This is done because XLA's CPU gather from each member's own packed
    table (a batched operand) is many times slower (docs/performance.md, Episodic evaluation)."""
    if (rows is None) != (member is None):
        raise ValueError("rows and member go together: a stacked MDP's successor_rows and this MDP's index in it; "
                         f"got rows={'None' if rows is None else rows.shape} and member={member!r}")
    _assert_actions(mdp, actions)
    if rows is not None:
        S, A, K = mdp.n_states, mdp.n_actions, mdp.max_successors
        chex.assert_shape(rows, (None, S, A, 2 * K + 1), custom_message="rows: successor_rows [M, S, A, 2K+1]")
        chex.assert_rank(member, 0, custom_message="member: this MDP's index in the stack, a scalar")
    V_H = jnp.zeros((mdp.n_states,), mdp.R.dtype)
    backup = _deterministic_backup(mdp, rows, member)
    return _backward(backup, V_H, (jnp.arange(mdp.H), actions[: mdp.H]), False)


# ---------------------------------------------------------------------------------------------------------------
# Average reward
# ---------------------------------------------------------------------------------------------------------------
