"""Pieces shared by the deep agents: the emission table from the spec, hyperparameter casting and checks, the Adam
optimiser (optax) with traced hyperparameters, and evaluation of a network on every row of the emission table (paper
§3.1, App. A.2)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax

from jaxmdp._asserts import assert_observation, assert_transition
from jaxmdp._checks import check_range
from jaxmdp.experiment.agent_interface import MDPSpec, RunnerHints, Transition

__all__ = [
    "DEEP_HINTS",
    "observation_table",
    "observation_shape",
    "assert_act",
    "assert_update",
    "cast_hparams",
    "check_whole",
    "make_optimizer",
    "optimizer_step",
    "on_table",
]

#: The deep agents' runner hints: every member takes its gradient steps at the same steps (a schedule of the step
#: count and hyperparameters), so the runner plans the whole batch at once; planning rounds gathered and scattered
#: every member's replay buffer at every step and halved DQN's throughput (docs/performance.md, Deep agents).
DEEP_HINTS = RunnerHints(plans_together=True)


def observation_table(spec: MDPSpec, agent_name: str, episodic: bool | None = None) -> jax.Array:
    """The noiseless emission table of the spec, ``[S, *obs]`` (continuous) or ``[H, S, *obs]`` (episodic).

    Raises ``ValueError`` for a plain MDP (no table: a deep agent observes emissions, not state indices), for a
    table of the wrong shape, and, when ``episodic`` is given, for an MDP of the other setting.
    """
    table = spec.observations
    if table is None:
        raise ValueError(
            f"{agent_name} is a deep agent: it needs a BlockMDP or an emission table; pass "
            "jaxmdp.block_mdp(mdp, 'state_info') instead of a plain MDP"
        )
    if episodic is not None and spec.episodic != episodic:
        kind = "episodic" if episodic else "continuous"
        raise ValueError(f"{agent_name} is {kind}; the MDP is not (use the other setting's agent)")
    lead = 2 if spec.episodic else 1
    expected = (spec.H, spec.n_states) if spec.episodic else (spec.n_states,)
    if table.ndim <= lead or tuple(table.shape[:lead]) != expected:
        want = "[H, S, *obs]" if spec.episodic else "[S, *obs]"
        raise ValueError(
            f"{agent_name}: the emission table must have shape {want} = {expected + ('*obs',)} for this MDP; "
            f"got {table.shape}"
        )
    return table


def observation_shape(table: jax.Array, episodic: bool) -> tuple[int, ...]:
    """Shape of one observation (a row of the table)."""
    return tuple(table.shape[2 if episodic else 1 :])


def assert_act(state: Any, obs: jax.Array, h: jax.Array) -> None:
    """chex, at trace time: ``obs`` is one row of the state's emission table and ``h`` an integer scalar
    (:func:`jaxmdp._asserts.assert_observation`)."""
    assert_observation(obs, h, observation_shape(state.observations, state.episodic))


def assert_update(state: Any, tr: Transition) -> None:
    """chex, at trace time: ``tr`` is one member's step with observations of the emission table's row shape
    (:func:`jaxmdp._asserts.assert_transition`)."""
    assert_transition(tr, observation_shape(state.observations, state.episodic))


def cast_hparams(hparams: Any, dtype: Any = jnp.float32) -> Any:
    """The hyperparameters with every numeric leaf an array: ``int32`` for the fields whose class default is an
    integer (periods and counts such as ``sgd_period``), ``dtype`` (the agent's float type) for every other one.

    The field decides, not the value: ``discount=1`` given as a Python int becomes ``1.0`` of ``dtype`` and
    ``sgd_period=2.0`` becomes ``2`` (``check_hparams`` rejects a non-whole one). Static fields (sizes such as
    ``width``) are not leaves and stay as given. ``hparams`` is a ``flax.struct`` dataclass (a grid: leaves with a
    leading axis).
    """
    updates = {}
    for field in dataclasses.fields(hparams):
        if not field.metadata.get("pytree_node", True):
            continue
        default = field.default
        integer = isinstance(default, int) and not isinstance(default, bool)
        updates[field.name] = jnp.asarray(getattr(hparams, field.name)).astype(jnp.int32 if integer else dtype)
    return hparams.replace(**updates)


def check_whole(name: str, value: Any, low: int, high: float = np.inf) -> None:
    """Raise ``ValueError`` unless every entry of ``value`` (a scalar or a grid) is a whole number in
    ``[low, high]``."""
    check_range(name, value, low, high)
    x = np.asarray(value, np.float64)
    if not np.all(x == np.round(x)):
        raise ValueError(f"{name} must be a whole number; got {x.reshape(-1)[np.argmax(x != np.round(x))]}")


def make_optimizer(hparams: Any) -> optax.GradientTransformation:
    """Adam (Kingma & Ba 2015) at ``hparams.learning_rate`` with optax's defaults otherwise (beta_1 0.9, beta_2 0.999,
    eps 1e-8; bsuite's), after a clip of the gradient to global norm ``max_grad_norm`` when the hyperparameters have
    that field. Built inside the traced functions, so the numeric hyperparameters may be traced (a vmapped grid)."""
    adam = optax.adam(hparams.learning_rate)
    if hasattr(hparams, "max_grad_norm"):
        return optax.chain(optax.clip_by_global_norm(hparams.max_grad_norm), adam)
    return adam


def optimizer_step(params: Any, grads: Any, opt_state: Any, hparams: Any) -> tuple[Any, Any]:
    """One step of :func:`make_optimizer`: ``params - learning_rate * m_hat / (sqrt(v_hat) + eps)`` on the (clipped)
    gradient; returns ``(params, opt_state)``."""
    updates, opt_state = make_optimizer(hparams).update(grads, opt_state, params)
    return optax.apply_updates(params, updates), opt_state


def on_table(fn: Callable[[jax.Array], jax.Array], table: jax.Array, episodic: bool) -> jax.Array:
    """``fn`` (one observation -> ``[A]``) applied to every row of the table: ``[S, A]`` or ``[H, S, A]``."""
    lead = table.shape[: 2 if episodic else 1]
    rows = table.reshape((-1,) + observation_shape(table, episodic))
    out = jax.vmap(fn)(rows)
    return out.reshape(lead + out.shape[1:])
