"""Dynamic programming on MDPs: discounted, finite-horizon and average-reward, all jittable and vmappable.

Every routine works on one *model* and leaves batching to ``jax.vmap``. A model is either an :class:`~jaxmdp.MDP`
(expectations then use its successor lists, ``O(S A K)`` per backup) or a dense ``[S, A, S]`` kernel (used by agents
that plan on sampled or estimated kernels). Rewards default to the MDP's ``R`` and can be overridden, e.g. with
``-R`` for the worst policy or with an estimate.

The modules, by topic (every name is importable from this package):

* :mod:`~jaxmdp.dynamic_programming.backups`: one Bellman backup, greedy and fixed policies, and :func:`compiled`;
* :mod:`~jaxmdp.dynamic_programming.iteration`: the value-iteration loop :func:`relative_value_iteration`;
* :mod:`~jaxmdp.dynamic_programming.discounted`: discounted values, ``Q(s,a) = R(s,a) + gamma * sum_s' P(s'|s,a)
  V(s')`` (paper §2.1);
* :mod:`~jaxmdp.dynamic_programming.finite_horizon`: finite horizon ``H``, ``V_H = 0``, ``Q_h = R + P V_{h+1}``,
  ``V_h = max_a Q_h`` for ``h = H-1..0``;
* :mod:`~jaxmdp.dynamic_programming.markov_chains` and :mod:`~jaxmdp.dynamic_programming.average_reward`: average
  reward, the gain ``rho = d^T P*_pi r_pi`` of a policy from a start distribution ``d`` (``P*_pi`` the Cesàro limit of
  its chain), by Grassmann-Taksar-Heyman elimination (:mod:`jaxmdp.gth`).

Greedy policies break ties deterministically towards the lowest action index.

One iterative loop serves the value iterations here and in the agents: :func:`relative_value_iteration` iterates a
Bellman backup given as a function ``backup(u) -> Q[S, A]``, so the same loop solves an ordinary MDP
(:func:`value_iteration`), UCRL2's extended MDP (the backup maximises over a confidence set of kernels) and
optimistic PSRL's extended MDP (the backup maximises over sampled kernels). :func:`optimal_gain` runs the same
iteration with arithmetic of its own, for its tighter tolerance (see there).

The routines with loops are jitted (:func:`compiled`), so that eager calls compile once per shape; the loops that take
a backup function (:func:`relative_value_iteration`, :func:`policy_iteration_by`) are meant to be called inside the
caller's ``jit``.

Every public routine asserts the ranks, shapes and dtypes of its arrays with chex (``jaxmdp._asserts``: an MDP or
kernel against its ``S`` and ``A``, policies, values and rewards against those). The assertions run while tracing
and read no values, so the compiled program is the same without them; a wrong input fails with chex's
``AssertionError`` naming the argument instead of deep inside XLA.
"""

from jaxmdp.dynamic_programming import (
    average_reward,
    backups,
    discounted,
    finite_horizon,
    iteration,
    markov_chains,
)
from jaxmdp.dynamic_programming.average_reward import *  # noqa: F403
from jaxmdp.dynamic_programming.backups import *  # noqa: F403
from jaxmdp.dynamic_programming.discounted import *  # noqa: F403
from jaxmdp.dynamic_programming.finite_horizon import *  # noqa: F403
from jaxmdp.dynamic_programming.iteration import *  # noqa: F403
from jaxmdp.dynamic_programming.markov_chains import *  # noqa: F403

# Not public: the model type of the signatures, and two steps of the exact gain that tests exercise on their own.
from jaxmdp.dynamic_programming.average_reward import _irreducible  # noqa: F401
from jaxmdp.dynamic_programming.backups import Model  # noqa: F401
from jaxmdp.dynamic_programming.markov_chains import _gain_after_elimination  # noqa: F401

__all__ = [
    *backups.__all__,
    *iteration.__all__,
    *discounted.__all__,
    *finite_horizon.__all__,
    *markov_chains.__all__,
    *average_reward.__all__,
]
