"""Functional environment API in the style of gymnax 1.0: ``reset`` and ``step`` with the MDP as the params pytree.

Observations are state indices (tabular). Episodes (docs/families.md §1.8): ``reset`` draws ``s0 ~ P0`` and sets the
in-episode step ``h = 0``; every ``step`` takes one action, so an episode has exactly ``horizon`` actions taken at
``h = 0 .. horizon - 1``, each earning a reward. The step whose action is the last one of the episode reports
``terminated = True``; the environment then resets itself: the returned observation and state are those of a fresh
episode, and ``info["final_observation"]`` is the state the last action reached (never observed by the agent in the
reference). Continuous MDPs never terminate and ``h`` counts steps since the reset. ``truncated`` is always False
(there is no time limit other than the horizon).

Rewards are drawn from the transition's distribution (``Beta`` or point mass, see :class:`~jaxmdp.MDP`). Everything
is jittable and vmaps over keys, states and stacked MDPs. A step costs ``O(K)`` (successor lists, one entry of
the reward tables, sparse start lists; :func:`step`). An invalid action raises ``ValueError`` when it is concrete
and is a flagged no-op under ``jit`` (NaN reward, the state does not move; :func:`step`).

BlockMDPs (:class:`jaxmdp.BlockMDP`): ``reset`` and ``step`` take one wherever they take an MDP and return its
observations (emission-table row plus a noise draw from ``noise_key(key)``) instead of state indices, with the same
state trajectory, rewards and flags as the underlying MDP for the same keys. ``info["final_observation"]`` is then
the observation of the state reached (the very sample returned when the episode goes on; all zeros past an
episode's end, as the reference), ``info["final_state"]`` that state's index and ``info["state"]`` the index of the
returned observation's state.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp import struct
from jaxmdp.blockmdp.block_mdp import BlockMDP, noise_key, observe
from jaxmdp.mdp import MDP
from jaxmdp.sampling import fused_random
from jaxmdp.sampling.beta_shared import sample_beta_shared

__all__ = ["EnvState", "reset", "step", "step_member", "sample_action", "sample_next_state", "sample_reward"]


class EnvState(struct.PyTreeNode):
    """Environment state: the current state index and the in-episode step ``h``."""

    state: jax.Array
    h: jax.Array


# Start lists up to this length are searched by comparing every entry (vectorises best); longer ones by an unrolled
# binary search (O(log K0) gathers).
_COMPARE_ALL_STARTS = 32


def _read(x: jax.Array, member: jax.Array | None, *index: Any) -> jax.Array:
    """``x[index]`` of an MDP's table, or with ``member`` of member ``member``'s table in a stacked MDP: one gather
    from the stack."""
    return x[index] if member is None else x[(member, *index)]


def _start_from_uniform(u: jax.Array, mdp: MDP, member: jax.Array | None = None) -> jax.Array:
    """Inverse CDF over the sparse start list: ``start[j]`` for the first ``j`` with ``u * total < start_cdf[j]``."""
    if mdp.max_starts == 1:  # static: one start state, nothing to draw
        return _read(mdp.start, member, 0)
    cdf = _read(mdp.start_cdf, member)
    method = "compare_all" if mdp.max_starts <= _COMPARE_ALL_STARTS else "scan_unrolled"
    j = jnp.searchsorted(cdf, u * cdf[-1], side="right", method=method)
    return _read(mdp.start, member, jnp.minimum(j, mdp.max_starts - 1))


def _slot_from_uniform(
    u: jax.Array, mdp: MDP, state: jax.Array, action: jax.Array, member: jax.Array | None = None
) -> jax.Array:
    """Inverse CDF over the successor list of ``(state, action)``: the slot ``k`` of the next state."""
    if mdp.max_successors == 1:  # static: deterministic dynamics, nothing to draw (the inverse CDF would give 0)
        return jnp.zeros((), jnp.int32)
    cdf = jnp.cumsum(_read(mdp.succ_p, member, state, action))
    return jnp.minimum(jnp.sum(cdf <= u * cdf[-1]), cdf.shape[-1] - 1)


def _reward_draw(key: jax.Array, mdp: MDP, mean: jax.Array, conc: jax.Array) -> jax.Array:
    """Beta(mean * conc, (1 - mean) * conc) where ``conc > 0``, else ``mean`` (no draw compiled if rewards are all
    point masses)."""
    if not mdp.stochastic_rewards:  # static: no Beta anywhere, no draw compiled
        return mean
    stochastic = conc > 0
    alpha = jnp.where(stochastic, mean * conc, 1.0)
    beta = jnp.where(stochastic, (1.0 - mean) * conc, 1.0)
    draw = sample_beta_shared(key, alpha, beta, dtype=mdp.dtype)
    return jnp.where(stochastic, draw, mean)


def sample_action(key: jax.Array, mdp: MDP) -> jax.Array:
    """A uniformly random valid action. Uses one uniform draw, so padding an MDP does not change the draw."""
    mdp = mdp.mdp if isinstance(mdp, BlockMDP) else mdp
    n_valid = jnp.sum(mdp.action_mask)
    a = jnp.floor(fused_random.uniform(key, dtype=jnp.float32) * n_valid).astype(jnp.int32)
    return jnp.minimum(a, n_valid - 1)


def sample_next_state(key: jax.Array, mdp: MDP, state: jax.Array, action: jax.Array) -> jax.Array:
    """Draw ``s' ~ P(. | state, action)`` by inverse CDF over the successor list (``O(K)``)."""
    k = _slot_from_uniform(fused_random.uniform(key, dtype=mdp.dtype), mdp, state, action)
    return mdp.succ[state, action, k].astype(jnp.int32)


def sample_reward(
    key: jax.Array,
    mdp: MDP,
    state: jax.Array,
    action: jax.Array,
    next_state: jax.Array,
) -> jax.Array:
    """Draw the reward of ``(state, action, next_state)``: Beta(mean*conc, (1-mean)*conc) if ``conc > 0``, else mean.

    Beta draws use :func:`jaxmdp.sampling.beta_shared.sample_beta_shared` (exact; a member of a ``vmap``-ed batch
    gets bit for bit its single call's value), because it makes the step markedly cheaper than
    :func:`jaxmdp.sampling.beta_sampling.sample_beta`, itself much cheaper than ``jax.random.beta`` under ``vmap``
    (docs/performance.md, Environment step). MDPs whose static ``stochastic_rewards`` is False (no Beta reward
    anywhere, recorded at construction) compile no draw at all: the reward is the mean.
    """
    mean = mdp.reward_mean[state, action, next_state]
    return _reward_draw(key, mdp, mean, mdp.reward_conc[state, action, next_state])


def reset(key: jax.Array, mdp: MDP | BlockMDP) -> tuple[jax.Array, EnvState]:
    """Start an episode: ``s0 ~ P0``, ``h = 0``. Returns ``(obs, state)``."""
    if isinstance(mdp, BlockMDP):
        _, state = reset(key, mdp.mdp)
        return observe(noise_key(key), mdp, state.state, state.h), state
    s0 = _start_from_uniform(fused_random.uniform(key, dtype=mdp.dtype), mdp)
    return s0, EnvState(state=s0, h=jnp.zeros((), jnp.int32))


def _concrete(x: Any) -> np.ndarray | None:
    """``x`` as a numpy array when it is concrete (not traced), else None."""
    if isinstance(x, jax.core.Tracer):
        return None
    try:
        return np.asarray(x)
    except (jax.errors.ConcretizationTypeError, jax.errors.TracerArrayConversionError):
        return None


def _check_action(action: Any, mdp: MDP) -> None:
    """Eager check of a concrete ``action``: an integer in ``[0, A)`` that the MDP's ``action_mask`` allows."""
    a = _concrete(action)
    if a is None:
        return
    A = mdp.n_actions
    if a.dtype.kind not in "iu" and not (a.dtype.kind == "f" and np.all(a == np.round(a))):
        raise ValueError(f"action must be an integer in [0, {A}) (A = {A}); got {action!r}")
    if np.any((a < 0) | (a >= A)):
        raise ValueError(f"action must be an integer in [0, {A}) (A = {A}); got {a.tolist()}")
    mask = _concrete(mdp.action_mask)
    if mask is not None and mask.ndim == 1 and not np.all(mask[a.astype(np.int64)]):
        raise ValueError(
            f"action {a.tolist()} is a padded action of this MDP (action_mask is False); valid actions: "
            f"{np.nonzero(mask)[0].tolist()} of A = {A}"
        )


def step(
    key: jax.Array, state: EnvState, action: jax.Array, mdp: MDP | BlockMDP
) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, jax.Array, dict[str, Any]]:
    """Take ``action``: returns ``(obs, state, reward, terminated, truncated, info)`` with auto-reset.

    ``info`` holds ``final_observation`` (the state reached by this action, before any reset) and ``discount``
    (0 on termination, else 1); for a BlockMDP see the module docstring.

    Cost ``O(K)``: the next state is an inverse CDF over the successor list, its reward distribution one entry
    ``reward_mean[s, a, s']`` / ``reward_conc[s, a, s']`` (a single-element gather), and the reset of a finished
    episode an inverse CDF over the sparse start list (nothing at all with one start state; computed branch-free, as
    ``vmap`` would turn a ``cond`` into a select anyway). Random numbers per step: one key split (reward key, uniform
    key) and one draw of two uniforms (next state, reset); what a step cannot use is not compiled (no Beta draw
    without Beta rewards, no uniforms when ``K = 1`` and there is one start state), the stream staying the same.

    Invalid actions: a concrete ``action`` outside ``[0, A)`` or masked out by ``action_mask`` (a padded action of a
    stacked MDP) raises ``ValueError``. A traced one cannot raise: the step is then a no-op that is flagged, i.e. the
    state and ``h`` stay as they were, the reward is NaN, ``terminated`` is False and ``final_observation`` is the
    current state; no array row other than the current state's (clamped) row is read.
    """
    if isinstance(mdp, BlockMDP):
        _, new_state, reward, terminated, truncated, info = step(key, state, action, mdp.mdp)
        obs = observe(noise_key(key), mdp, new_state.state, new_state.h)
        final = jnp.where(terminated, jnp.zeros_like(obs), obs)
        info = {**info, "final_observation": final, "final_state": info["final_observation"], "state": new_state.state}
        return obs, new_state, reward, terminated, truncated, info
    _check_action(action, mdp)
    return _step(key, state, action, mdp, None)


def step_member(
    key: jax.Array, state: EnvState, action: jax.Array, mdps: MDP, member: jax.Array
) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, jax.Array, dict[str, Any]]:
    """:func:`step` of member ``member`` of the stacked MDP ``mdps`` (a leading MDP axis on every array): the same
    result bit for bit as ``step`` on that member's MDP, with every table read one gather from the stack.

    What a lockstep grid of several MDPs should call under ``vmap``: ``step`` on each member's own MDP (a
    ``tree.map(lambda x: x[member], mdps)``) makes XLA copy every member's tables, the ``[S, A, S]`` reward tables
    included, out of the stack (hoisted out of the step loop, then read per member), which slows the step down
    (docs/performance.md, Environment step).

    A concrete ``member`` outside ``[0, M)`` or ``action`` outside ``[0, A)`` raises ``ValueError``; a traced invalid
    action is the flagged no-op of :func:`step`. BlockMDPs are not supported (``TypeError``).
    """
    if not isinstance(mdps, MDP) or mdps.T.ndim != 4:
        raise TypeError(f"mdps must be a stacked MDP (jaxmdp.stack: T of shape [M, S, A, S]); got {type(mdps).__name__}"
                        + (f" with T of shape {mdps.T.shape}" if isinstance(mdps, MDP) else ""))
    i = _concrete(member)
    M = mdps.T.shape[0]
    if i is not None and np.any((i < 0) | (i >= M)):
        raise ValueError(f"member must be an index in [0, {M}) (the stack holds {M} MDPs); got {i.tolist()}")
    _check_action(action, mdps)
    return _step(key, state, action, mdps, member)


def _step(
    key: jax.Array, state: EnvState, action: jax.Array, mdp: MDP, member: jax.Array | None
) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, jax.Array, dict[str, Any]]:
    """The body of :func:`step` (``member`` None) and :func:`step_member`."""
    # One key for the reward and two uniforms for the next and reset states: fewer PRNG calls than three splits,
    # each hashed in the step's own fusions (jax.random's values, jaxmdp.sampling.fused_random).
    k_reward, k_uniform = fused_random.split(key)
    u_next, u_reset = fused_random.uniform(k_uniform, (2,), dtype=mdp.dtype)
    action = jnp.asarray(action, jnp.int32)
    a = jnp.clip(action, 0, mdp.n_actions - 1)
    valid = (action == a) & _read(mdp.action_mask, member, a)
    k = _slot_from_uniform(u_next, mdp, state.state, a, member)
    s_next = _read(mdp.succ, member, state.state, a, k).astype(jnp.int32)
    reward = _reward_draw(
        k_reward, mdp, _read(mdp.reward_mean, member, state.state, a, s_next),
        _read(mdp.reward_conc, member, state.state, a, s_next),
    )
    h_next = state.h + 1
    terminated = ((h_next >= _read(mdp.horizon, member)) & valid) if mdp.episodic else jnp.zeros((), bool)
    s_reset = _start_from_uniform(u_reset, mdp, member) if mdp.episodic else state.state
    s_next = jnp.where(valid, s_next, state.state)
    new_state = EnvState(
        state=jnp.where(terminated, s_reset, s_next),
        h=jnp.where(terminated, 0, jnp.where(valid, h_next, state.h)).astype(jnp.int32),
    )
    info = {"final_observation": s_next, "discount": 1.0 - terminated.astype(mdp.dtype)}
    reward = jnp.where(valid, reward, jnp.nan)
    return new_state.state, new_state, reward, terminated, jnp.zeros((), bool), info
