"""The environmental value norm (paper §2.2, Maillard et al. 2014; docs/measures.md §4).

``C = max_{(s, a)} sqrt( Var_{s' ~ P(.|s,a)} V(s') )`` with ``V`` the optimal value: the largest one-step standard
deviation of the optimal value function.

``variant="paper"`` (default):

* continuous, discounted: ``V = V*_gamma`` exact (:func:`jaxmdp.dynamic_programming.solve_discounted`);
* episodic, discounted: the time-augmented MDP on the reachable pairs (``(h, s) -> (h+1, s')``, ``(H-1, s) -> (0,
  s0) ~ P0``, reward ``R(s, a)`` everywhere). Every path from a pair to the next reset takes exactly ``H - h`` steps,
  so its optimal values are ``V(h, s) = W_h(s) + gamma^(H-h) c`` with ``W`` the ``gamma``-discounted backward
  induction with zero terminal value and ``c`` one scalar; a constant shift leaves every one-step variance unchanged,
  so ``C`` is the largest of ``Var_{P(.|s,a)} W_{h+1}`` over reachable ``(h, s)``, ``h < H-1``, and
  ``Var_{P0} W_0`` (the reset rows). Exact, ``O(H S A K)``;
* ``discounted=False``: the same with the optimal *bias* in place of ``V``. Continuous: the bias of the gain-optimal
  policy of :func:`~jaxmdp.dynamic_programming.optimal_gain`, computed exactly from the deviation matrix (below).
  Episodic: on the time-augmented MDP every policy's bias is ``W_h(s) - (H - h) g`` with ``W`` the undiscounted
  finite-horizon values, so it is the episodic formula above with ``gamma = 1``.

``variant="colosseum"`` reproduces the reference (docs/measures.md §4.1-4.3, [quirk] [paper≠code]):

* ``C_code = max_{s,a} sqrt( sum_s' P(s'|s,a) (V(s') - E[s', a])^2 )`` with ``E[s, a] = sum_s' P(s'|s,a) V(s')``:
  the centring is the expected next value *of the next state under the same action*, so this is not a variance;
* ``V`` from the reference's value iteration (``gamma = 0.99``, ``eps = 1e-3``, :mod:`hardness.reference_vi`);
* ``0`` when every transition and every reward of the *base* MDP is deterministic (even an episodic MDP with several
  starting states, whose continuous form is stochastic);
* episodic: the same formula on the reference's continuous form (:func:`jaxmdp.episodic.continuous_form`, with its
  reset-column quirk), which must be built on the host and passed as ``continuous_form`` under ``jit``/``vmap``;
* ``discounted=False``: ``V`` replaced by the bias of the greedy policy of the discounted values. The reference
  approximates it with ``P^1000`` and a 60 s wall-clock cut; here it is exact.

The exact bias of a policy's chain is :func:`jaxmdp.dynamic_programming.chain_bias` (Puterman Thm. A.7, dense
``O(S^3)``).
"""

from __future__ import annotations

import functools

import chex
import jax
import jax.numpy as jnp

from hardness.reference_vi import reference_value_iteration, uses_jacobi
from hardness.result import MeasureResult
from jaxmdp import dynamic_programming as dp
from jaxmdp._asserts import assert_mdp
from jaxmdp._checks import Variant, check_range, check_variant
from jaxmdp.episodic import ContinuousForm, continuous_form, reachable_pairs
from jaxmdp.mdp import MDP

__all__ = ["value_norm", "value_norm_from", "optimal_values", "deterministic_base"]


#: Tolerance for "probability one" when deciding that a transition is deterministic.
_DETERMINISTIC_ATOL = 1e-6


def deterministic_base(mdp: MDP) -> jax.Array:
    """The reference's shortcut test: every valid ``(s, a)`` has a single next state and every reward distribution
    on a possible transition is a point mass (``reward_conc == 0``)."""
    assert_mdp(mdp)
    valid = mdp.state_mask[:, None] & mdp.action_mask[None, :]
    det_t = jnp.all((jnp.max(mdp.succ_p, axis=-1) >= 1.0 - _DETERMINISTIC_ATOL) | ~valid)
    det_r = jnp.all((mdp.reward_conc == 0) | (mdp.T <= 0) | ~valid[:, :, None])
    return det_t & det_r


def _variance(succ: jax.Array, succ_p: jax.Array, V: jax.Array, centre: jax.Array) -> jax.Array:
    """``sum_k p[s,a,k] (V[succ[s,a,k]] - centre)^2`` with ``centre`` broadcastable to ``[S, A, K]``."""
    return jnp.sum(succ_p * (V[succ] - centre) ** 2, axis=-1)


def _textbook(succ, succ_p, V) -> jax.Array:
    E = jnp.sum(succ_p * V[succ], axis=-1)
    return _variance(succ, succ_p, V, E[..., None])


def _code_form(succ, succ_p, V) -> jax.Array:
    E = jnp.sum(succ_p * V[succ], axis=-1)  # [S, A]
    A = succ.shape[1]
    centre = E[succ, jnp.arange(A)[None, :, None]]  # E[s', a] for every successor slot
    return _variance(succ, succ_p, V, centre)


def _masked_sqrt_max(var: jax.Array, mask: jax.Array) -> jax.Array:
    return jnp.sqrt(jnp.maximum(jnp.max(jnp.where(mask, var, -jnp.inf)), 0.0))


# ---------------------------------------------------------------------------------------------------------------
# Paper
# ---------------------------------------------------------------------------------------------------------------


def _paper_continuous(mdp: MDP, gamma: float, discounted: bool, values=None) -> MeasureResult:
    mask = mdp.state_mask[:, None] & mdp.action_mask[None, :]
    if discounted:
        _, V, converged = optimal_values(mdp, gamma, "paper") if values is None else values
    else:
        opt = dp.optimal_gain(mdp)
        pi = opt.policy
        V = dp.chain_bias(dp.policy_matrix(mdp, pi), dp.policy_rewards(mdp, pi))
        converged = opt.converged
    return MeasureResult.make(_masked_sqrt_max(_textbook(mdp.succ, mdp.succ_p, V), mask), converged)


def _paper_episodic(mdp: MDP, gamma: float) -> MeasureResult:
    reach = reachable_pairs(mdp)  # [H, S]
    # Discounted backward induction = undiscounted induction on the kernel gamma * P (successor lists scaled).
    _, W = dp.finite_horizon_value_iteration(mdp.replace(succ_p=gamma * mdp.succ_p))  # W[H + 1, S]
    H = mdp.H
    var_body = jax.vmap(lambda w: _textbook(mdp.succ, mdp.succ_p, w))(W[1 : H + 1])  # [H, S, A]: Var of W_{h+1}
    reset_var = mdp.P0 @ (W[0] - mdp.P0 @ W[0]) ** 2
    h = jnp.arange(H)[:, None, None]
    var = jnp.where(h == mdp.horizon - 1, reset_var, var_body)
    mask = reach[:, :, None] & mdp.action_mask[None, None, :]
    return MeasureResult.make(_masked_sqrt_max(var, mask), True)


# ---------------------------------------------------------------------------------------------------------------
# Colosseum
# ---------------------------------------------------------------------------------------------------------------


def _colosseum_on(succ, succ_p, R, row_mask, action_mask, gamma, discounted, max_iter, values=None) -> MeasureResult:
    if values is None:
        jacobi = uses_jacobi(succ_p, row_mask, action_mask)
        values = reference_value_iteration(succ, succ_p, R, gamma, jacobi=jacobi, row_mask=row_mask, max_iter=max_iter)
    Q, V, converged = values
    if not discounted:
        pi = dp.greedy(Q, action_mask)
        V = dp.chain_bias(dp.successor_policy_matrix(succ, succ_p, pi), jnp.sum(pi * R, axis=-1))
    mask = row_mask[:, None] & action_mask[None, :]
    return MeasureResult.make(_masked_sqrt_max(_code_form(succ, succ_p, V), mask), converged)


def _colosseum(
    mdp: MDP, cf: ContinuousForm | None, gamma: float, discounted: bool, max_iter: int, values=None
) -> MeasureResult:
    if mdp.episodic:
        res = _colosseum_on(cf.succ, cf.succ_p, cf.R, cf.row_mask, cf.action_mask, gamma, discounted, max_iter)
    else:
        res = _colosseum_on(
            mdp.succ, mdp.succ_p, mdp.R, mdp.state_mask, mdp.action_mask, gamma, discounted, max_iter, values
        )
    det = deterministic_base(mdp)
    return MeasureResult.make(jnp.where(det, 0.0, res.value), res.converged | det)


def optimal_values(mdp: MDP, gamma, variant: str, max_iter: int = 1_000_000):
    """``(Q, V, converged)`` of a continuous MDP as each variant defines them: exact (``"paper"``,
    :func:`~jaxmdp.dynamic_programming.solve_discounted`) or the reference's value iteration (``"colosseum"``).
    Shared by the value norm and the gap sum."""
    assert_mdp(mdp)
    chex.assert_rank(gamma, 0, custom_message="gamma: a scalar discount")
    if variant == "paper":
        sol = dp.solve_discounted(mdp, gamma)
        return sol.Q, sol.V, sol.converged
    jacobi = uses_jacobi(mdp.succ_p, mdp.state_mask, mdp.action_mask)
    return reference_value_iteration(
        mdp.succ, mdp.succ_p, mdp.R, gamma, jacobi=jacobi, row_mask=mdp.state_mask, max_iter=max_iter
    )


def value_norm_from(mdp, cf, gamma, variant, discounted, max_iter, values=None) -> MeasureResult:
    """Traceable core of :func:`value_norm`; ``values`` = :func:`optimal_values` (continuous) if already known."""
    S, A = assert_mdp(mdp)
    chex.assert_rank(gamma, 0, custom_message="gamma: a scalar discount")
    if cf is not None:
        chex.assert_rank(cf.succ, 3, custom_message="continuous_form.succ: one MDP's form [N, A, K] (vmap a stack)")
        chex.assert_equal_shape([cf.succ, cf.succ_p], custom_message="continuous_form: succ and succ_p [N, A, K]")
    if values is not None:
        chex.assert_shape(values[:2], [(S, A), (S,)], custom_message="values: (Q [S, A], V [S], converged)")
    if variant == "paper":
        if mdp.episodic:
            return _paper_episodic(mdp, gamma if discounted else 1.0)
        return _paper_continuous(mdp, gamma, discounted, values)
    return _colosseum(mdp, cf, gamma, discounted, max_iter, values)


_value_norm = functools.partial(jax.jit, static_argnames=("variant", "discounted", "max_iter"))(value_norm_from)


def value_norm(
    mdp: MDP,
    gamma: float = 0.99,
    *,
    variant: Variant = "paper",
    discounted: bool = True,
    continuous_form: ContinuousForm | None = None,
    max_iter: int = 1_000_000,
) -> MeasureResult:
    """The environmental value norm of ``mdp`` (module docstring).

    Args:
      mdp: a single MDP (``jax.vmap`` over a stacked batch of equal shapes for many; MDPs of different sizes:
        :func:`hardness.measures_many`).
      gamma: discount factor in ``(0, 1)``.
      variant: ``"paper"`` (exact variance of the optimal values) or ``"colosseum"`` (the reference's formula).
      discounted: ``False`` for the undiscounted variant (optimal bias instead of discounted values).
      continuous_form: colosseum variant of an episodic MDP only: the reference's continuous form
        (:func:`jaxmdp.episodic.continuous_form`, or :func:`jaxmdp.episodic.stack_continuous_forms` for a batch).
        Built automatically outside ``jit``; required under ``jit``/``vmap`` because its pair order comes from a
        host-side depth-first search.
      max_iter: sweep budget of the reference's value iteration (colosseum variant).
    """
    check_variant(variant)
    check_range("gamma", gamma, 0.0, 1.0, low_open=True, high_open=True)
    cf = None
    if variant == "colosseum" and mdp.episodic:
        cf = continuous_form if continuous_form is not None else _host_continuous_form(mdp)
    return _value_norm(mdp.strip(), cf, jnp.asarray(gamma, mdp.dtype), variant, bool(discounted), int(max_iter))


def _host_continuous_form(mdp: MDP) -> ContinuousForm:
    if isinstance(mdp.T, jax.core.Tracer):
        raise ValueError(
            "the colosseum value norm of an episodic MDP needs continuous_form=jaxmdp.episodic.continuous_form(mdp) "
            "built outside jit/vmap (its pair order comes from a host-side depth-first search)"
        )
    if mdp.T.ndim != 3:
        raise ValueError("pass continuous_form=jaxmdp.episodic.stack_continuous_forms([...]) for a stacked batch")
    return continuous_form(mdp)
