"""Trace-time shape, rank and dtype assertions (chex) at the array boundaries of the public routines: dynamic
programming, the hardness measures and the agents' ``act`` and ``update``.

They read static shapes and dtypes only, never values, so under ``jit`` they run once while tracing and the compiled
program is the same with or without them (``chex.disable_asserts()`` turns them off). They complement the host-side
``ValueError`` checks of :mod:`jaxmdp._checks`, which validate what a user passes with a message naming the parameter:
these catch arrays whose shapes disagree with the MDP's ``S``, ``A``, ``H`` (a stacked MDP where one MDP is expected,
a policy of another MDP, a state index given as a vector), which would otherwise fail deep inside XLA or broadcast
into a wrong answer. A failure is chex's ``AssertionError``, its message ending with the argument's name and layout.
"""

from __future__ import annotations

from typing import Any

import chex

from jaxmdp.mdp import MDP

__all__ = ["assert_mdp", "assert_model", "assert_policy", "assert_chain", "assert_transition", "assert_observation"]


def assert_mdp(mdp: Any, name: str = "mdp") -> tuple[int, int]:
    """One (unstacked) :class:`~jaxmdp.MDP`'s arrays agree with its ``S`` states and ``A`` actions: ``T`` and the
    reward distribution ``[S, A, S]``, ``R[S, A]``, the successor lists ``[S, A, K]``, ``P0`` and ``state_mask``
    ``[S]``, ``action_mask[A]``, a scalar ``horizon``; probabilities and rewards floating, successors integer, masks
    boolean. Returns ``(S, A)``."""
    chex.assert_rank(mdp.T, 3, custom_message=f"{name}.T: one MDP's kernel [S, A, S] (jax.vmap over a stacked batch)")
    S, A = mdp.n_states, mdp.n_actions
    fields = {
        "T": (S, A, S), "R": (S, A), "P0": (S,), "reward_mean": (S, A, S), "reward_conc": (S, A, S),
        "succ": (S, A, None), "succ_p": (S, A, None), "state_mask": (S,), "action_mask": (A,), "horizon": (),
    }
    for field, shape in fields.items():
        chex.assert_shape(getattr(mdp, field), shape, custom_message=f"{name}.{field}")
    chex.assert_type([mdp.T, mdp.R, mdp.P0, mdp.succ_p], float, custom_message=f"{name}: T, R, P0, succ_p floating")
    chex.assert_type([mdp.succ, mdp.state_mask, mdp.action_mask], [int, bool, bool],
                     custom_message=f"{name}: succ integer, state_mask and action_mask boolean")
    return S, A


def assert_model(model: Any, rewards: Any = None) -> tuple[int, int]:
    """A model of dynamic programming: an MDP (:func:`assert_mdp`) or a dense floating kernel ``[S, A, S]``, and
    ``rewards`` (when given) ``[S, A]`` floating. Returns ``(S, A)``."""
    if isinstance(model, MDP):
        S, A = assert_mdp(model, "model")
    else:
        chex.assert_rank(model, 3, custom_message="model: a dense kernel [S, A, S] or an MDP")
        chex.assert_type(model, float, custom_message="model: a dense kernel of probabilities")
        S, A = model.shape[0], model.shape[1]
        chex.assert_axis_dimension(model, 2, S, custom_message="model: a dense kernel [S, A, S]")
    if rewards is not None:
        chex.assert_shape(rewards, (S, A), custom_message="rewards: [S, A]")
        chex.assert_type(rewards, float, custom_message="rewards")
    return S, A


def assert_policy(pi: Any, S: int, A: int, name: str = "pi", *, time_indexed: bool = False) -> None:
    """``pi`` is a stationary policy ``[S, A]``, or with ``time_indexed`` also one per time step ``[H, S, A]``."""
    if time_indexed:
        chex.assert_rank(pi, {2, 3}, custom_message=f"{name}: a policy [S, A] or [H, S, A]")
        chex.assert_shape(pi, (..., S, A), custom_message=f"{name}: a policy [S, A] or [H, S, A]")
    else:
        chex.assert_shape(pi, (S, A), custom_message=f"{name}: a policy [S, A]")


def assert_chain(P: Any, name: str = "P") -> int:
    """``P`` is a floating square matrix ``[S, S]`` (a Markov chain); returns ``S``."""
    chex.assert_rank(P, 2, custom_message=f"{name}: a chain [S, S]")
    chex.assert_type(P, float, custom_message=f"{name}: a chain of probabilities")
    S = P.shape[0]
    chex.assert_axis_dimension(P, 1, S, custom_message=f"{name}: a square chain [S, S]")
    return S


def assert_observation(obs: Any, h: Any, obs_shape: tuple[int, ...] | None = ()) -> None:
    """What an agent's ``act`` receives for one member: ``obs`` of ``obs_shape`` (``()``: a state index, integer;
    ``None``: not checked, for an agent that ignores it) and the step ``h``, an integer scalar."""
    chex.assert_rank(h, 0, custom_message="h: the in-episode step of one member, a scalar")
    chex.assert_type(h, int, custom_message="h: the in-episode step")
    if obs_shape is not None:
        chex.assert_shape(obs, obs_shape, custom_message=f"obs: one observation {list(obs_shape)}")
        if obs_shape == ():
            chex.assert_type(obs, int, custom_message="obs: a state index")


def assert_transition(tr: Any, obs_shape: tuple[int, ...] | None = ()) -> None:
    """One member's :class:`~jaxmdp.experiment.agent_interface.Transition`: ``obs`` and ``next_obs`` of
    ``obs_shape`` (as in :func:`assert_observation`), a scalar integer ``action`` and ``h``, a scalar floating
    ``reward`` and a scalar ``terminated``."""
    for field in ("action", "reward", "h", "terminated"):
        chex.assert_rank(getattr(tr, field), 0, custom_message=f"transition.{field}: one member's step, a scalar")
    chex.assert_type([tr.action, tr.reward, tr.h], [int, float, int],
                     custom_message="transition: action and h integer, reward floating")
    if obs_shape is not None:
        for field in ("obs", "next_obs"):
            chex.assert_shape(getattr(tr, field), obs_shape,
                              custom_message=f"transition.{field}: one observation {list(obs_shape)}")
        if obs_shape == ():
            chex.assert_type([tr.obs, tr.next_obs], int, custom_message="transition: obs and next_obs state indices")
