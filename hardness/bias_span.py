"""The span of the optimal bias, ``sp(h*)`` (Bartlett & Tewari 2009, REGAL; docs/measures.md §7.3).

For a continuous MDP, a solution ``(g*, h*)`` of the average-reward optimality equation

    ``h*(s) + g* = max_a [ r(s, a) + sum_s' P(s'|s, a) h*(s') ]``   for every state ``s``

has the optimal gain ``g*`` (the same from every start) and the optimal bias ``h*``; the measure is

    ``sp(h*) = max_s h*(s) - min_s h*(s)``.

Bartlett & Tewari (2009, "REGAL: A regularization based algorithm for reinforcement learning in weakly communicating
MDPs", UAI) bound the regret of REGAL by ``O(sp(h*) S sqrt(A T))``; ``sp(h*) <= D`` (the diameter) and it can be far
smaller. A constant added to ``h*`` solves the equation too, so only the span is meaningful.

Uniqueness: for a *unichain* MDP (every deterministic policy has one recurrent class) the solution ``h*`` is unique
up to a constant, so ``sp(h*)`` is well defined. (Any solution is, up to a constant, the bias of a policy that attains
the maximum; two such policies' recurrent classes must intersect, since one policy following each on its own closed
class would have two; a solution's difference is constant on both classes and squeezed between the two constants
elsewhere.) In a weakly communicating MDP that is not unichain the solutions may differ by more than a constant (two
optimal loops joined by zero-reward moves): the value is then the span of the solution found, the bias of the policy
that policy iteration ends with (below). An MDP whose optimal gain depends on the start state (several closed classes
of different optimal gains) has no solution with a constant ``g*``: the result is ``inf`` with ``converged=False``.

How it is computed (exactly, up to the floating-point solves): Howard's policy iteration for average reward with
exact evaluation (Puterman 1994, §8.6). A deterministic policy whose chain has one recurrent class has the gain and
bias that solve

    ``(I - P_pi) h + g 1 = r_pi``,  ``h(s_ref) = 0``,

one dense ``S x S`` linear system (non-singular exactly for such a chain); a policy with several recurrent classes
(possible in a weakly communicating MDP) is evaluated through its Cesàro limit ``P*`` instead (``g = P* r``,
``h = (I - P + P*)^{-1} (r - g)``, Puterman Thm. A.7), which costs ``O(S^3 log)``. The policy is then improved where
some action beats it by more than the tolerance (ties keep the current action, so on a unichain MDP the iteration
cannot cycle), until no action does. It starts from the greedy policy of relative value iteration
(:func:`jaxmdp.dynamic_programming.optimal_gain`), which is usually already optimal, so that one or two solves
suffice. Relative value iteration alone certifies ``g*`` (its bounds) but not ``h*``: its error in ``h`` is its
stopping tolerance divided by how fast the aperiodic chain mixes, which nothing bounds. The result is *certified*:
``converged`` holds only when the final policy's gain is the same from every real state and its ``(g, h)``
satisfies the optimality equation there to within ``rtol (1 + |g| + max_s |h(s)|)`` (a solution with a constant
gain exists only where ``g* = g`` from every state, so a certified ``g`` is the optimal gain); otherwise the value is
``inf`` with ``converged=False``.

Padded states (an MDP of a stacked batch) are pinned to ``h = 0`` and left out of the span and of the certificate;
padded actions are never chosen. Cost: one ``O(S^3)`` solve and one ``O(S A K)`` backup per policy-iteration step,
after relative value iteration (``O(S^3 log)`` for a policy with several recurrent classes; under ``jax.vmap`` both
evaluations run, since a batched ``lax.cond`` computes both branches).
"""

from __future__ import annotations

import functools

import chex
import jax
import jax.numpy as jnp

from hardness.result import MeasureResult
from jaxmdp import dynamic_programming as dp
from jaxmdp import struct
from jaxmdp._asserts import assert_mdp
from jaxmdp._checks import check_int, check_range
from jaxmdp.jaxlib_workarounds.linalg import solve as linear_solve
from jaxmdp.mdp import MDP

__all__ = ["bias_span", "AverageRewardSolution", "average_reward_solution"]


class AverageRewardSolution(struct.PyTreeNode):
    """A solution of the average-reward optimality equation (:func:`average_reward_solution`).

    Attributes:
      gain: ``g*``, a scalar.
      bias: ``h*[S]`` with ``h*(s_ref) = 0`` at the first real state (``0`` at padded states).
      Q: ``r(s, a) + P(s, a) . h*``, ``[S, A]``.
      actions: the final policy, an action index per state (``[S]``, int32).
      tolerance: the certificate's tolerance ``rtol (1 + |g| + max_s |h(s)|)``.
      iterations: policy-iteration steps (linear solves) taken.
      converged: the equation holds at every real state to within ``tolerance``.
    """

    gain: jax.Array
    bias: jax.Array
    Q: jax.Array
    actions: jax.Array
    tolerance: jax.Array
    iterations: jax.Array
    converged: jax.Array


def _unichain(mdp: MDP, actions: jax.Array) -> jax.Array:
    """Whether the chain of the deterministic policy ``actions`` has one recurrent class among the real states
    (reachability on the chosen actions' successor lists; every recurrent state lies in the first one's class)."""
    states = jnp.arange(mdp.n_states)
    reach = dp.successor_reachability(mdp.succ[states, actions], mdp.succ_p[states, actions] > 0)
    recurrent = mdp.state_mask & jnp.all(~reach | reach.T, axis=1)
    return jnp.all(~recurrent | reach[jnp.argmax(recurrent)])


def _evaluate(mdp: MDP, actions: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Gain vector and bias of the deterministic policy ``actions``.

    One recurrent class: ``(I - P) h + g 1 = r``, ``h(s_ref) = 0`` (the gain takes the place of ``h(s_ref)`` among the
    unknowns; padded states' rows read ``h(s) = 0``), one ``O(S^3)`` solve. Several (possible in a weakly communicating
    MDP, and the system is then singular): ``g = P* r`` and the bias ``(I - P + P*)^{-1} (r - g)`` from the Cesàro
    limit (:func:`~jaxmdp.dynamic_programming.chain_bias`, ``O(S^3 log)``)."""
    S = mdp.n_states
    states = jnp.arange(S)
    real = mdp.state_mask
    dtype = mdp.dtype
    P = mdp.T[states, actions]
    r = jnp.where(real, mdp.R[states, actions], 0.0)
    eye = jnp.eye(S, dtype=dtype)

    def one_class():
        ref = jnp.argmax(real)
        M = (eye - P).at[:, ref].set(real.astype(dtype))
        M = jnp.where(real[:, None], M, eye)  # no real state moves to a padded one
        x = linear_solve(M, r)
        return jnp.full((S,), x[ref]), x.at[ref].set(0.0)

    def several():
        Pstar = dp.cesaro_limit(P)
        g = Pstar @ r
        return g, linear_solve(eye - P + Pstar, r - g)

    return jax.lax.cond(_unichain(mdp, actions), one_class, several)


def average_reward_solution(mdp: MDP, rtol: float | jax.Array = 1e-4, max_iter: int = 64) -> AverageRewardSolution:
    """``(g*, h*)`` of a continuous MDP by policy iteration with exact evaluation (module docstring); traceable
    (``max_iter`` static), one MDP (``jax.vmap`` for a batch)."""
    S, A = assert_mdp(mdp)
    chex.assert_rank(rtol, 0, custom_message="rtol: a scalar tolerance")
    real = mdp.state_mask
    ref = jnp.argmax(real)
    states = jnp.arange(S)
    start = dp.greedy_actions(dp.optimal_gain(mdp).Q, mdp.action_mask)

    def scale(g, h):
        return rtol * (1.0 + jnp.abs(g) + jnp.max(jnp.where(real, jnp.abs(h), 0.0)))

    def body(c):
        actions, _, _, _, _, it = c
        g, h = _evaluate(mdp, actions)
        Q = mdp.R + dp.expected_next_values(mdp, h)
        best = jnp.max(jnp.where(mdp.action_mask, Q, -jnp.inf), axis=-1)
        # Switch only where another action is better by more than the tolerance: ties keep the current action, so on
        # a unichain MDP the gain, then the bias, improves at every step and the iteration cannot cycle (Puterman
        # §8.6); elsewhere max_iter bounds it and the certificate decides.
        improve = real & (best > Q[states, actions] + scale(g[ref], h))
        new = jnp.where(improve, dp.greedy_actions(Q, mdp.action_mask), actions)
        return new, g, h, Q, jnp.any(improve), it + 1

    dtype = mdp.dtype
    init = (start, jnp.zeros((S,), dtype), jnp.zeros((S,), dtype), jnp.zeros((S, A), dtype), jnp.asarray(True),
            jnp.asarray(0))
    actions, gains, h, Q, changed, it = jax.lax.while_loop(lambda c: c[4] & (c[5] < max_iter), body, init)
    g = gains[ref]
    tol = scale(g, h)
    best = jnp.max(jnp.where(mdp.action_mask, Q, -jnp.inf), axis=-1)
    residual = jnp.where(real, jnp.abs(best - g - h), 0.0)
    spread = jnp.where(real, jnp.abs(gains - g), 0.0)  # a gain that depends on the start solves no equation
    finite = jnp.all(jnp.isfinite(gains)) & jnp.all(jnp.isfinite(h))
    converged = ~changed & finite & jnp.all(residual <= tol) & jnp.all(spread <= tol)
    return AverageRewardSolution(gain=g, bias=h, Q=Q, actions=actions, tolerance=tol, iterations=it,
                                 converged=converged)


def check_average_reward_args(name: str, mdp: MDP, rtol: float, max_iter: int) -> int:
    """Host-side checks shared by the average-reward measures: a continuous MDP, ``rtol`` in ``(0, 1)``,
    ``max_iter >= 1``; returns ``max_iter``."""
    if mdp.episodic:
        raise ValueError(
            f"{name} needs a continuous MDP: the average-reward optimality equation (gain and bias) belongs to the "
            "infinite-horizon setting; an episodic MDP has finite-horizon values instead (hardness.sum_reciprocal_gaps)"
        )
    check_range("rtol", rtol, 0.0, 1.0, low_open=True, high_open=True)
    return check_int("max_iter", max_iter, 1)


def bias_span(mdp: MDP, *, rtol: float = 1e-4, max_iter: int = 64) -> MeasureResult:
    """Span of the optimal bias ``sp(h*) = max_s h*(s) - min_s h*(s)`` of a continuous MDP (module docstring;
    Bartlett & Tewari 2009).

    Args:
      mdp: a continuous MDP (a stacked batch under ``jax.vmap``; padded states are left out).
      rtol: relative tolerance of the optimality-equation certificate and of policy improvement, in ``(0, 1)``;
        the solves are in the MDP's dtype (``mdp.astype(jnp.float64)`` with x64 enabled for slowly mixing MDPs).
      max_iter: most policy-iteration steps (each one ``O(S^3)`` solve).

    Returns:
      a :class:`MeasureResult`: ``sp(h*)``; ``inf`` with ``converged=False`` when no solution with a constant gain
      was certified (an optimal gain that depends on the start state, or a final policy with several recurrent
      classes).

    Raises:
      ValueError: for an episodic MDP, ``rtol`` outside ``(0, 1)`` or ``max_iter < 1``.
    """
    max_iter = check_average_reward_args("bias_span", mdp, rtol, max_iter)
    return _bias_span(mdp.strip(), jnp.asarray(rtol, mdp.dtype), max_iter)


@functools.partial(jax.jit, static_argnames=("max_iter",))
def _bias_span(mdp: MDP, rtol, max_iter):
    sol = average_reward_solution(mdp, rtol, max_iter)
    real = mdp.state_mask
    h = sol.bias
    span = jnp.max(jnp.where(real, h, -jnp.inf)) - jnp.min(jnp.where(real, h, jnp.inf))
    return MeasureResult.make(span, sol.converged)
