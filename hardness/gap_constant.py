"""The problem-dependent constant of the regret lower bound of Burnetas & Katehakis (1997) (docs/measures.md §7.4).

Burnetas & Katehakis ("Optimal adaptive policies for Markov decision processes", Math. Oper. Res. 22(1), 1997) show
that on an ergodic MDP with known rewards and unknown transition laws every uniformly good learner has
``liminf_T E[Regret_T] / log T >= C``, and give a learner that attains it, with

    ``C = sum_{(s, a) critical} Delta*(s, a) / K(s, a)``,

built from a solution ``(g*, h*)`` of the average-reward optimality equation (:mod:`hardness.bias_span`):

* the average-reward gaps ``Delta*(s, a) = g* + h*(s) - r(s, a) - P(s, a) . h*`` (``>= 0``, zero at the actions that
  attain the maximum of the equation; unchanged by a constant added to ``h*``);
* ``K(s, a) = inf { KL(P(s, a) || q) : r(s, a) + q . h* > g* + h*(s) }``, the smallest change of the transition law
  of ``(s, a)`` alone, in Kullback-Leibler divergence from the true law, that would make ``a`` better than the
  optimal actions at ``s``;
* a pair is *critical* when ``Delta*(s, a) > 0`` and ``K(s, a) < inf``: some admissible law makes it optimal.

Which laws ``q`` are admissible (``support``): Burnetas & Katehakis take the support of each transition law as known
(their index policy searches laws on it; Tewari & Bartlett's OLP, NIPS 2007, is presented as the variant that does not
need the supports), so ``support="transition"`` (default) admits the laws ``q`` on the successors of ``(s, a)``
(``q(s') > 0`` only where ``P(s'|s, a) > 0``): a deterministic transition is then known at once and no pair with one
is critical. ``support="all"`` admits every law on the MDP's states (``KL(P || q)`` is finite whenever ``q`` keeps
``P``'s support, so ``q`` may add states), the constant of a learner that does not know the supports.

``K`` is a KL projection onto a half-space, computed through its one-dimensional concave dual (Honda & Takemura 2010,
"An asymptotically optimal bandit algorithm for bounded support models", COLT: the dual of their ``K_inf``): with
``mu = g* + h*(s) - r(s, a)`` (the threshold ``q . h*`` must pass), ``u`` the largest ``h*`` on the admissible states,
and ``z(s') = (h*(s') - mu) / (u - mu) <= 1``,

    ``K = max_{0 <= t <= 1} sum_s' P(s'|s, a) log(1 - t z(s'))``   (``u > mu``; ``K = inf`` when ``u <= mu``),

whose derivative decreases in ``t``; its root (or ``t = 1`` when the derivative is still non-negative there, which
happens only when ``P`` puts no mass on the states where ``h* = u``) is found by bisection to the dtype's precision:
exact and jittable, ``O(S A K)`` per bisection step.

``form="reciprocal"`` gives ``sum_{Delta*(s, a) > 0} 1 / Delta*(s, a)`` instead: the average-reward analogue of the
paper's sum of reciprocal gaps (:mod:`hardness.gaps`, whose gaps are discounted), with no KL term.

Gaps up to the certificate's tolerance ``rtol (1 + |g*| + max_s |h*(s)|)`` count as zero (tied optimal actions). The
lower bound is proved for ergodic MDPs (every policy irreducible); on other MDPs whose optimality equation is solved
(unichain, or weakly communicating, :mod:`hardness.bias_span`) the value is the same formula at the ``h*`` found.
Padded states and actions are left out.
"""

from __future__ import annotations

import functools
from typing import Literal

import chex
import jax
import jax.numpy as jnp

from hardness.bias_span import average_reward_solution, check_average_reward_args
from hardness.result import MeasureResult
from jaxmdp._asserts import assert_mdp
from jaxmdp.mdp import MDP

__all__ = ["gap_constant", "average_reward_gaps", "kl_inf"]

Form = Literal["kl", "reciprocal"]
Support = Literal["transition", "all"]

#: Bisection steps of the dual of :func:`kl_inf`: enough to reach the precision of float64 on ``[0, 1]``.
_BISECTION_STEPS = 64


def kl_inf(p: jax.Array, x: jax.Array, mu: jax.Array, upper: jax.Array) -> jax.Array:
    """``inf { KL(p || q) : q . x >= mu }`` over the laws ``q`` on the points of ``x`` and on a point of value
    ``upper`` (``upper >= x`` wherever ``p > 0``), by the dual (module docstring): ``0`` when ``p . x >= mu``,
    ``inf`` when ``upper <= mu``. ``p`` and ``x`` are ``[K]`` (a law on ``K`` points, repeats allowed); scalars
    ``mu``, ``upper``. Jittable; vmaps."""
    chex.assert_equal_shape([p, x], custom_message="p and x: a law and its values [K]")
    chex.assert_rank([mu, upper], 0, custom_message="mu and upper: scalars")
    on = p > 0
    width = upper - mu
    feasible = width > 0
    z = jnp.where(on, (x - mu) / jnp.where(feasible, width, 1.0), 0.0)  # <= 1 on p's support

    def slope(t):  # derivative of sum p log(1 - t z), for t < 1 or where no mass sits at z = 1
        return -jnp.sum(jnp.where(on, p * z / jnp.where(on, 1.0 - t * z, 1.0), 0.0))

    at_top = jnp.any(on & (z >= 1.0))  # mass where h = upper: the objective falls to -inf at t = 1

    def bisect(_, c):
        lo, hi = c
        mid = 0.5 * (lo + hi)
        up = slope(mid) > 0
        return jnp.where(up, mid, lo), jnp.where(up, hi, mid)

    one = jnp.ones((), p.dtype)
    lo, hi = jax.lax.fori_loop(0, _BISECTION_STEPS, bisect, (jnp.zeros((), p.dtype), one))
    t = jnp.where(~at_top & (slope(one) >= 0), one, 0.5 * (lo + hi))
    value = jnp.sum(jnp.where(on, p * jnp.log1p(-t * z), 0.0))
    already = jnp.sum(p * x) >= mu
    return jnp.where(already, 0.0, jnp.where(feasible, jnp.maximum(value, 0.0), jnp.inf))


def average_reward_gaps(mdp: MDP, rtol: float | jax.Array = 1e-4, max_iter: int = 64):
    """``(Delta*[S, A], mask[S, A], solution)``: the average-reward gaps ``g* + h*(s) - Q*(s, a)`` clipped at 0
    (module docstring), the valid pairs, and the :class:`~hardness.bias_span.AverageRewardSolution` (its
    ``converged`` certifies them). Traceable (``max_iter`` static)."""
    assert_mdp(mdp)
    sol = average_reward_solution(mdp, rtol, max_iter)
    delta = jnp.maximum(sol.gain + sol.bias[:, None] - sol.Q, 0.0)
    mask = mdp.state_mask[:, None] & mdp.action_mask[None, :]
    return delta, mask, sol


def _constant(mdp: MDP, rtol, form: str, support: str, max_iter: int) -> MeasureResult:
    delta, mask, sol = average_reward_gaps(mdp, rtol, max_iter)
    gap = mask & (delta > sol.tolerance)
    if form == "reciprocal":
        terms = jnp.where(gap, 1.0 / jnp.where(gap, delta, 1.0), 0.0)
        return MeasureResult.make(jnp.sum(terms), sol.converged)
    h = sol.bias
    x = h[mdp.succ]  # [S, A, K]: h* at each successor slot
    mu = sol.gain + h[:, None] - mdp.R  # [S, A]: what q . h* must exceed
    if support == "transition":
        upper = jnp.max(jnp.where(mdp.succ_p > 0, x, -jnp.inf), axis=-1)
    else:
        upper = jnp.broadcast_to(jnp.max(jnp.where(mdp.state_mask, h, -jnp.inf)), mu.shape)
    K = jax.vmap(jax.vmap(kl_inf))(mdp.succ_p, x, mu, upper)
    critical = gap & jnp.isfinite(K) & (K > 0)
    terms = jnp.where(critical, delta / jnp.where(critical, K, 1.0), 0.0)
    return MeasureResult.make(jnp.sum(terms), sol.converged)


_gap_constant = functools.partial(jax.jit, static_argnames=("form", "support", "max_iter"))(_constant)


def gap_constant(
    mdp: MDP,
    *,
    form: Form = "kl",
    support: Support = "transition",
    rtol: float = 1e-4,
    max_iter: int = 64,
) -> MeasureResult:
    """The gap-based constant of the regret lower bound of Burnetas & Katehakis (1997) of a continuous MDP (module
    docstring).

    Args:
      mdp: a continuous MDP (a stacked batch under ``jax.vmap``; padded states and actions are left out).
      form: ``"kl"``: ``sum_{critical (s, a)} Delta*(s, a) / K(s, a)``, the lower bound's constant; ``"reciprocal"``:
        ``sum_{Delta*(s, a) > 0} 1 / Delta*(s, a)``.
      support: the laws the inner infimum ranges over (``form="kl"``): ``"transition"`` (on the successors of
        ``(s, a)``, Burnetas & Katehakis's known supports) or ``"all"`` (on every state).
      rtol: the optimality equation's certificate tolerance (:func:`hardness.bias_span`); gaps up to
        ``rtol (1 + |g*| + max |h*|)`` count as zero.
      max_iter: most policy-iteration steps.

    Returns:
      a :class:`MeasureResult` (``inf`` with ``converged=False`` when the optimality equation was not solved).

    Raises:
      ValueError: for an episodic MDP, an unknown ``form`` or ``support``, ``rtol`` outside ``(0, 1)`` or
        ``max_iter < 1``.
    """
    if form not in ("kl", "reciprocal"):
        raise ValueError(f"form must be 'kl' or 'reciprocal'; got {form!r}")
    if support not in ("transition", "all"):
        raise ValueError(f"support must be 'transition' or 'all'; got {support!r}")
    max_iter = check_average_reward_args("gap_constant", mdp, rtol, max_iter)
    return _gap_constant(mdp.strip(), jnp.asarray(rtol, mdp.dtype), form, support, max_iter)
