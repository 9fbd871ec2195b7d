"""Probe MDPs with known action values for the deep agents' learning tests (bsuite's and rejax's probe environments:
constant reward, action-dependent reward, one-step discounting), all of one shape (``S = A = 2``, ``H = 2``) so that
one compiled runner per agent serves every probe, and the agents observe one-hot states (``jnp.eye(2)``).

Every probe is the chain ``s0 -> s1 -> s0`` (both actions move along it); episodic episodes start in ``s0`` and last
``H = 2`` steps, so ``(h=0, s0)`` and ``(h=1, s1)`` are the reachable pairs. Known answers are computed here by
backward induction / value iteration in numpy (independent of jaxmdp); by hand:

* ``constant`` (reward 0.7 everywhere): episodic ``gamma = 1``: ``Q(s1) = 0.7``, ``Q(s0) = 1.4``; continuous
  ``gamma = 0.5``: ``Q = 0.7 / (1 - 0.5) = 1.4`` everywhere;
* ``arms`` (``s0``: arms pay 0.2 and 0.9; ``s1``: 0.5): the greedy action in ``s0`` is arm 1; episodic:
  ``Q(s0) = (0.7, 1.4)``; continuous ``gamma = 0.5``: ``V(s0) = 1.15 / 0.75``, ``Q(s0, 0) = 0.2 + 0.5 V(s1)``;
* ``discounting`` (reward 1 in ``s1`` only): episodic ``gamma = 0.9``: ``Q(s0) = gamma * 1 = 0.9``; continuous
  ``gamma = 0.5``: ``Q(s0) = gamma / (1 - gamma^2) = 2/3``, ``Q(s1) = 1 / (1 - gamma^2) = 4/3``.
"""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

import agents
import jaxmdp
from tests.agent_loop import RunResult, grid_seeds, make_grid_runner

PROBES = ("constant", "arms", "discounting")
CHAIN = np.zeros((2, 2, 2))
CHAIN[0, :, 1] = 1.0
CHAIN[1, :, 0] = 1.0
REWARDS = {
    "constant": np.full((2, 2), 0.7),
    "arms": np.array([[0.2, 0.9], [0.5, 0.5]]),
    "discounting": np.array([[0.0, 0.0], [1.0, 1.0]]),
}


def discount(probe: str, episodic: bool) -> float:
    if not episodic:
        return 0.5
    return 0.9 if probe == "discounting" else 1.0


def probe_mdp(probe: str, episodic: bool) -> jaxmdp.MDP:
    return jaxmdp.custom_mdp(CHAIN, R=REWARDS[probe], H=2 if episodic else None)


def table(episodic: bool) -> jax.Array:
    """One-hot observations: ``[H, S, S]`` (no time information) or ``[S, S]``."""
    return jnp.broadcast_to(jnp.eye(2), (2, 2, 2)) if episodic else jnp.eye(2)


def true_q(probe: str, episodic: bool) -> np.ndarray:
    """``Q*`` of the reachable observations, ``[S, A]``: row ``s`` is ``Q*_h(s)`` at the step ``h = s`` where ``s`` is
    visited (episodic), or the discounted ``Q*(s)`` (continuous)."""
    R, g = REWARDS[probe], discount(probe, episodic)
    if episodic:
        Q = np.zeros((3, 2, 2))  # Q[H] = 0
        for h in (1, 0):
            Q[h] = R + g * CHAIN @ Q[h + 1].max(-1)
        return np.stack([Q[0, 0], Q[1, 1]])
    Q = np.zeros((2, 2))
    for _ in range(2000):
        Q = R + g * CHAIN @ Q.max(-1)
    return Q


def stack(*hparams: Any) -> Any:
    """Hyperparameter sets stacked along a leading grid axis."""
    return jax.tree.map(lambda *x: jnp.stack([jnp.asarray(v) for v in x]), *hparams)


@functools.cache
def _cached_runner(name: str, n_steps: int):
    """``run(keys[E, B], mdp, hparams[E], table) -> RunResult`` with ``[E, B]`` leading axes, actions and rewards
    traced (:func:`~tests.agent_loop.make_grid_runner`)."""
    return make_grid_runner(agents.get(name), n_steps, trace=True)


def run_epsilon_grid(
    name: str, probe: str, n_steps: int, epsilons: tuple[float, ...], base: int = 0, n_seeds: int = 4, **hparams: Any
) -> RunResult:
    """The agent ``name`` on ``probe`` for ``n_steps`` steps: its default hyperparameters with ``hparams``, the probe's
    discount and one member set per epsilon of ``epsilons``, each of ``n_seeds`` members (``[E, B]`` leading axes, every
    member its own key from ``base``: :func:`~tests.agent_loop.grid_seeds`; actions and rewards traced; one compiled
    runner per agent and ``n_steps``)."""
    agent = agents.get(name)
    hp = agent.default_hparams.replace(**hparams, discount=discount(probe, agent.episodic))
    grid = stack(*(hp.replace(epsilon=e) for e in epsilons))
    run = _cached_runner(name, n_steps)
    return run(grid_seeds(len(epsilons), n_seeds, base), probe_mdp(probe, agent.episodic), grid, table(agent.episodic))


def reachable_q(q: np.ndarray, episodic: bool) -> np.ndarray:
    """``[..., S, A]`` values of the reachable observations (the rows that :func:`true_q` gives) from a Q-table
    ``[..., H, S, A]`` (episodic: ``(h=0, s0)`` and ``(h=1, s1)``) or ``[..., S, A]``."""
    return np.stack([q[..., 0, 0, :], q[..., 1, 1, :]], axis=-2) if episodic else q
