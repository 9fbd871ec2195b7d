"""Values of the reference policies (optimal, worst, uniformly random) that regrets are measured against.

Episodic MDPs (docs/measures.md §2.2): exact backward induction. ``value`` is the expected ``H``-step return from the
start distribution, ``sum_s P0(s) V_0(s)``; ``state_values`` are the ``V_0(s)`` of every state. The worst policy is
optimal for ``-R``. Both variants agree.

Continuous MDPs (paper §2.1): ``value`` is the average reward (gain) from ``P0``; ``state_values`` the gain from every
state.

* ``variant="paper"`` (default): the optimal and worst policies are gain-optimal for ``R`` and ``-R``
  (:func:`~jaxmdp.dynamic_programming.optimal_gain`): ``rho* = max_pi rho^pi`` and ``rho^- = min_pi rho^pi`` as in the
  paper's regret normalisation (App. E).
* ``variant="colosseum"``: the reference's choice (docs/measures.md §2.1, [paper≠code]): the greedy policies of the
  ``gamma = 0.99`` discounted optimal values of ``R`` and ``-R``, evaluated for their gain. They coincide with the
  paper's whenever the rewarding cycle is short compared with ``1 / (1 - gamma)`` steps.

Everything is jittable (``variant`` is static) and vmaps over a stacked batch.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmdp import dynamic_programming as dp
from jaxmdp import struct
from jaxmdp._checks import Variant, check_variant
from jaxmdp.mdp import MDP

__all__ = ["ReferenceValues", "reference_values", "optimal_value", "worst_value", "random_value", "optimal_policy"]



class ReferenceValues(struct.PyTreeNode):
    """Values and policies of the optimal, worst and uniformly random policies.

    Policies are ``[S, A]`` (continuous) or ``[H, S, A]`` (episodic, time-indexed).
    """

    optimal: jax.Array
    worst: jax.Array
    random: jax.Array
    optimal_state_values: jax.Array
    worst_state_values: jax.Array
    random_state_values: jax.Array
    optimal_policy: jax.Array
    worst_policy: jax.Array
    random_policy: jax.Array


def _check_variant(variant: str) -> None:
    check_variant(variant)


def _episodic(mdp: MDP) -> ReferenceValues:
    mask = mdp.action_mask
    Q_opt, V_opt = dp.finite_horizon_value_iteration(mdp)
    Q_neg, V_neg = dp.finite_horizon_value_iteration(mdp, rewards=-mdp.R)
    pi_opt = dp.greedy(Q_opt, mask)
    pi_worst = dp.greedy(Q_neg, mask)
    pi_rand = dp.uniform_policy(mdp, (mdp.H,))
    _, V_rand = dp.finite_horizon_policy_evaluation(mdp, pi_rand)
    V_worst = -V_neg
    return ReferenceValues(
        optimal=mdp.P0 @ V_opt[0],
        worst=mdp.P0 @ V_worst[0],
        random=mdp.P0 @ V_rand[0],
        optimal_state_values=V_opt[0],
        worst_state_values=V_worst[0],
        random_state_values=V_rand[0],
        optimal_policy=pi_opt,
        worst_policy=pi_worst,
        random_policy=pi_rand,
    )


def _continuous(mdp: MDP, variant: Variant, gamma: float) -> ReferenceValues:
    mask = mdp.action_mask
    if variant == "paper":
        pi_opt = dp.optimal_gain(mdp).policy
        pi_worst = dp.optimal_gain(mdp, rewards=-mdp.R).policy
    else:
        pi_opt = dp.greedy(dp.solve_discounted(mdp, gamma).Q, mask)
        pi_worst = dp.greedy(dp.solve_discounted(mdp, gamma, rewards=-mdp.R).Q, mask)
    pi_rand = dp.uniform_policy(mdp)
    # One traced gain evaluation looped over the three policies (lax.map), not three inlined copies: the same
    # numbers, a third of the program to compile (docs/performance.md, Compilation).
    pis = jnp.stack([pi.astype(mdp.dtype) for pi in (pi_opt, pi_worst, pi_rand)])
    g_opt, g_worst, g_rand = jax.lax.map(lambda pi: dp.gain_vector(mdp, pi), pis)
    return ReferenceValues(
        optimal=mdp.P0 @ g_opt,
        worst=mdp.P0 @ g_worst,
        random=mdp.P0 @ g_rand,
        optimal_state_values=g_opt,
        worst_state_values=g_worst,
        random_state_values=g_rand,
        optimal_policy=pi_opt,
        worst_policy=pi_worst,
        random_policy=pi_rand,
    )


@dp.compiled("variant", "gamma")
def reference_values(mdp: MDP, variant: Variant = "paper", gamma: float = 0.99) -> ReferenceValues:
    """Values of the optimal, worst and random policies (see the module docstring; ``gamma`` is used only by the
    ``colosseum`` variant of continuous MDPs).

    Jitted (:func:`~jaxmdp.dynamic_programming.compiled`; ``variant`` and ``gamma`` static, so ``gamma`` is a Python
    number): an eager call compiles once per shape, whatever the MDP's labels."""
    check_variant(variant)
    return _episodic(mdp) if mdp.episodic else _continuous(mdp, variant, gamma)


def optimal_value(mdp: MDP, variant: Variant = "paper") -> jax.Array:
    """Optimal episodic return ``sum P0 V*_0`` or optimal gain ``rho*``."""
    return reference_values(mdp, variant).optimal


def worst_value(mdp: MDP, variant: Variant = "paper") -> jax.Array:
    """Worst episodic return or worst gain ``rho^-``."""
    return reference_values(mdp, variant).worst


def random_value(mdp: MDP, variant: Variant = "paper") -> jax.Array:
    """Episodic return or gain of the uniformly random policy."""
    return reference_values(mdp, variant).random




def optimal_policy(mdp: MDP) -> jax.Array:
    """The optimal policy of :func:`reference_values` (``variant="paper"``) alone, jitted: time-indexed ``[H, S, A]``
    by backward induction (episodic) or gain-optimal ``[S, A]`` (continuous)."""
    return _optimal_policy(mdp.strip())


@jax.jit
def _optimal_policy(mdp: MDP) -> jax.Array:
    if mdp.episodic:
        return dp.greedy(dp.finite_horizon_value_iteration(mdp)[0], mdp.action_mask)
    return dp.optimal_gain(mdp).policy
