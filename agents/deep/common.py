"""Pieces shared by the deep agents: the emission table from the spec, hyperparameter casting and checks, Adam with a
traced learning rate, and evaluation of a network on every row of the emission table (paper §3.1, App. A.2)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax

from jaxmdp._checks import check_range
from jaxmdp.experiment.agent_interface import MDPSpec

__all__ = ["observation_table", "observation_shape", "cast_hparams", "check_whole", "adam", "adam_step", "on_table"]


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


def cast_hparams(hparams: Any) -> Any:
    """Numeric leaves as ``int32`` (integer-valued fields such as periods) or ``float32`` arrays."""

    def cast(x):
        x = jnp.asarray(x)
        return x.astype(jnp.int32 if jnp.issubdtype(x.dtype, jnp.integer) else jnp.float32)

    return jax.tree.map(cast, hparams)


def check_whole(name: str, value: Any, low: int, high: float = np.inf) -> None:
    """Raise ``ValueError`` unless every entry of ``value`` (a scalar or a grid) is a whole number in
    ``[low, high]``."""
    check_range(name, value, low, high)
    x = np.asarray(value, np.float64)
    if not np.all(x == np.round(x)):
        raise ValueError(f"{name} must be a whole number; got {x.reshape(-1)[np.argmax(x != np.round(x))]}")


#: Adam's moment estimates (Kingma & Ba 2015) with optax's defaults (beta_1 0.9, beta_2 0.999, eps 1e-8); the step
#: size is applied by :func:`adam_step` so that the learning rate can be a traced hyperparameter.
adam = optax.scale_by_adam()


def adam_step(params: Any, grads: Any, opt_state: Any, learning_rate: jax.Array) -> tuple[Any, Any]:
    """One Adam step ``params - learning_rate * m_hat / (sqrt(v_hat) + eps)``; returns ``(params, opt_state)``."""
    direction, opt_state = adam.update(grads, opt_state, params)
    return jax.tree.map(lambda p, d: p - learning_rate * d, params, direction), opt_state


def on_table(fn: Callable[[jax.Array], jax.Array], table: jax.Array, episodic: bool) -> jax.Array:
    """``fn`` (one observation -> ``[A]``) applied to every row of the table: ``[S, A]`` or ``[H, S, A]``."""
    lead = table.shape[: 2 if episodic else 1]
    rows = table.reshape((-1,) + observation_shape(table, episodic))
    out = jax.vmap(fn)(rows)
    return out.reshape(lead + out.shape[1:])
