"""The extended MDP of optimistic posterior sampling and its planner (Agrawal & Jia 2017; docs/agents.md §4).

Continuous PSRL (:mod:`agents.psrl_continuous`) draws ``psi`` candidate kernels per pair and plans on the *extended
MDP* whose action ``(a, k)`` in ``s`` has candidate ``k``'s kernel for ``(s, a)``; UCRL2's extended value iteration
(:mod:`agents.extended_value_iteration`) is the other optimistic planner of the package. This module holds the
candidates (:func:`draws`, :func:`extended_draws`) and the planner (:func:`extended_policy_iteration`, and
:func:`best_candidates` for relative value iteration); the agent's ``plan`` composes them with its epochs.

The plan never builds the extended MDP's ``[S, A max_psi, S]`` kernel (:func:`draws`, :func:`extended_policy_iteration`;
:func:`candidate_kernels` and :func:`extended_mdp` materialise it for tests). A simple optimistic candidate's
expectation is ``p^-(s, a) . V + missing(s, a) V[z_k(s, a)]``, so a backup costs ``O(S A K)`` for ``p^- . V`` (``p^-``
is zero off the observed next states: it is kept at the ``K`` successor slots, :class:`Draws`) and
``O(max_psi S A)`` for the states ``z`` (kept as ``[max_psi, S, A]`` indices). Posterior candidates (pairs at ``eta``)
are Dirichlet draws: the plan keeps those of the first ``M = min(S A, 2^22 / (max_psi S))`` pairs at ``eta``
(``[max_psi, M, S]``, drawn once, only when some pair of some member of a ``vmap`` is at ``eta``); should more pairs be
at ``eta``, it uses a draw of every pair's rows instead, drawn again at each backup one slot ``[S, A, S]`` at a time
from the same keys (the same bits each time). Within ``T = 500 000`` steps at most ``T / eta`` pairs reach ``eta``,
fewer than ``M`` at every size of the benchmark. An improvement step keeps per pair the best candidate (value and slot)
and per state the best real action, a policy being a real action and a candidate slot per state (:class:`_Choice`); an
evaluation solves ``(I - gamma P_pi) V = r_pi`` for the chosen rows, built only where the solve reads them (the states
whose row is not a jump and the states jumped to). When there are too many of those (late in a run, when most chosen
rows carry observed mass) and the MDP's band order is known, the chosen ``p^-`` rows are banded in it (they lie on
the MDP's successors) and their missing mass jumps to few states: a banded elimination with a low-rank correction;
otherwise the whole ``[S, S]`` system.
A plan's working memory is ``O(S^2 + max_psi S A)`` per member (kept draws aside). A plan in which no pair is at
``eta`` (nearly all of a run's plans) uses *lean* draws (:attr:`Draws.lean`): no kept rows and no posterior branches
in the planner, the same candidates and plan. With more than ``M`` pairs at ``eta`` (e.g. optimism off, where every
pair is), every backup pays ``psi`` Dirichlet draws of ``[S, A, S]``: a few per discounted plan, one per sweep of
relative value iteration.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp

from agents import estimated_model as em
from agents.posteriors import (
    COLOSSEUM_DIRICHLET_OFFSET,
    dirichlet_concentration,
    dirichlet_sample,
    normal_gamma_sample,
)
from agents.tabular_common import copy_action_zero, max_and_first_argmax, only_if
from jaxmdp import dynamic_programming as dp
from jaxmdp import struct
from jaxmdp._checks import Variant
from jaxmdp.sampling import fused_random

if TYPE_CHECKING:
    from agents.psrl_continuous import PSRLContinuousState

__all__ = [
    "KEEP_LIMIT",
    "JUMP_STATES",
    "BAND_TARGETS",
    "Draws",
    "draws",
    "candidate_kernels",
    "extended_mdp",
    "colosseum_extended_rewards",
    "extended_draws",
    "at_eta",
    "best_candidates",
    "extended_policy_iteration",
]


# The posterior rows that a plan keeps: those of the first M pairs at eta, M = min(S A, KEEP_LIMIT / (max_psi S))
# (``max_psi M S`` floats, 16 MiB a member). Above M pairs at eta, the plan uses a draw of all pairs' rows instead,
# drawn again from the same keys at every backup. For T = 500 000 at most T / eta pairs reach eta: 52 at S = 948
# (eta 9 480, M = 73), 125 at S = 400 (M = 174); Taxi (108 x 6, psi 17) keeps all its 648 pairs.
KEEP_LIMIT = 1 << 22


def _p_minus(counts: jax.Array, n1: jax.Array, log4s: jax.Array, colosseum: bool) -> jax.Array:
    """Simple optimistic sampling's lower row ``p^- = p_hat - min(sqrt(3 p_hat ln(4S) / n) + 3 ln(4S) / n, p_hat)``
    at next-state counts ``counts[..., n_next]`` (float) of pairs with ``n1 = max(1, N(s, a))[..., None]`` visits;
    ``n = n1``, or (``colosseum``) the reference's per-next-state ``max(1, N(s, a, s'))``. Elementwise, so the slots'
    values equal the dense row's at the same next states, and an unobserved next state gets exactly 0."""
    p_hat = counts / n1
    n_dev = jnp.maximum(counts, 1.0) if colosseum else n1
    return p_hat - jnp.minimum(jnp.sqrt(3.0 * p_hat * log4s / n_dev) + 3.0 * log4s / n_dev, p_hat)


class Draws(struct.PyTreeNode):
    """One plan's candidates in structured form (module docstring): candidate ``k`` of ``(s, a)`` is
    ``p^-(s, a) + missing[s, a] e_z[k, s, a]`` where ``posterior[s, a]`` is False, else a Dirichlet draw from the
    posterior concentration of the pair's counts: ``kept[k, m]`` for pair ``pairs[m]`` (the first ``M`` pairs at
    ``eta``, then the fill value ``S A``), or, when more than ``M`` pairs are at ``eta`` (``overflow``), row ``(s, a)``
    of :meth:`draw`. ``active[k]``: slot ``k < psi``. ``lean`` (static): drawn for a plan in which no pair is at
    ``eta``, without kept rows (``M = 0``); the planner then leaves out every posterior path.

    ``p^-`` (:func:`_p_minus`) is non-zero only at observed next states, so it is held at the pair's successor slots
    (``p_minus[S, A, K]`` at ``slot_states``) and backed up in ``O(S A K)``. Nor is the dense concentration kept: the
    posterior rows are drawn from the count rows of the pairs drawn, scattered from the slots."""

    slot_counts: jax.Array  # [S, A, K] int32: N(s, a, s') at the slots
    slot_states: jax.Array  # [S, A, K] int32
    p_minus: jax.Array  # [S, A, K]: p^- at the slots
    missing: jax.Array  # [S, A]
    z: jax.Array  # [max_psi, S, A] int32, real states
    posterior: jax.Array  # [S, A] bool: N(s, a) >= eta
    concentration: jax.Array  # [3]: (prior 1/S, omega, kappa) of the posterior concentration
    state_mask: jax.Array  # [S]
    key: jax.Array
    active: jax.Array  # [max_psi] bool
    pairs: jax.Array  # [M] int32 flat pair indices s A + a
    kept: jax.Array  # [max_psi, M, S]
    order: jax.Array | None = None  # [S]: the MDP's band order (SuccessorCounts.order), or None
    bandwidth: int | None = struct.field(pytree_node=False, default=None)
    offset: float = struct.field(pytree_node=False, default=0.0)
    colosseum: bool = struct.field(pytree_node=False, default=False)
    scaled: bool = struct.field(pytree_node=False, default=False)
    lean: bool = struct.field(pytree_node=False, default=False)

    @property
    def any_posterior(self) -> jax.Array:
        return jnp.any(self.posterior)

    @property
    def overflow(self) -> jax.Array:
        return jnp.sum(self.posterior) > self.pairs.shape[0]

    def alpha(self, counts: jax.Array) -> jax.Array:
        """The posterior concentration of count rows ``counts[..., S]``: ``1/S + N`` on the real states, or Agrawal &
        Jia's ``(N + omega) / kappa`` (``scaled``)."""
        prior, omega, kappa = self.concentration
        if self.scaled:
            return jnp.where(self.state_mask, (counts.astype(self.missing.dtype) + omega) / kappa, 0.0)
        return dirichlet_concentration(prior, counts, self.state_mask)

    def dense_counts(self) -> jax.Array:
        """The counts ``[S, A, S]`` scattered from the slots."""
        return em.scatter_slots(self.slot_states, self.slot_counts, self.state_mask.shape[0])

    def p_minus_dense(self) -> jax.Array:
        """``p^-`` of every pair, ``[S, A, S]``, scattered from the slots (for inspection; a plan never builds it)."""
        return em.scatter_slots(self.slot_states, self.p_minus, self.state_mask.shape[0])

    def p_minus_dot(self, V: jax.Array) -> jax.Array:
        """``p^-(s, a) . V`` for every pair, ``[S, A]``: on the slots, ``O(S A K)``."""
        return jnp.sum(self.p_minus * V[self.slot_states], axis=-1)

    def p_minus_rows(self, s: jax.Array, a: jax.Array) -> jax.Array:
        """The dense rows ``p^-(s[n], a[n])``, ``[n, S]``, scattered from the slots (distinct states, so exact)."""
        return em.scatter_slots(self.slot_states[s, a], self.p_minus[s, a], self.state_mask.shape[0])

    def p_minus_kernel(self) -> em.SparseKernel:
        """``p^-`` on the successor slots with its missing mass as the uniform part and the MDP's band order: its
        ``in_band`` says whether every ``p^-`` lies within ``bandwidth`` (the banded evaluations' premise)."""
        return em.SparseKernel(states=self.slot_states, probs=self.p_minus, uniform=self.missing,
                               state_mask=self.state_mask, order=self.order, bandwidth=self.bandwidth)

    def dirichlet(self, k: jax.Array, alpha: jax.Array) -> jax.Array:
        """Candidate ``k``'s posterior draws of concentrations ``alpha[..., S]`` (one key per candidate slot)."""
        return dirichlet_sample(jax.random.fold_in(self.key, k), alpha, offset=self.offset)

    def kept_alpha(self) -> jax.Array:
        """The concentrations ``[M, S]`` of the kept pairs, from their slots."""
        K = self.slot_states.shape[-1]
        m = jnp.minimum(self.pairs, self.missing.size - 1)
        S = self.state_mask.shape[0]
        rows = em.scatter_slots(self.slot_states.reshape(-1, K)[m], self.slot_counts.reshape(-1, K)[m], S)
        return self.alpha(rows)

    def draw(self, k: jax.Array) -> jax.Array:
        """Candidate ``k``'s posterior draws ``[S, A, S]`` for every pair, used when ``overflow``."""
        return self.dirichlet(k, self.alpha(self.dense_counts()))

    def posterior_draw(self, k: jax.Array) -> jax.Array:
        """The ``[S, A, S]`` posterior candidates ``k`` that a plan uses (rows of pairs not at ``eta`` meaningless)."""
        S = self.state_mask.shape[0]
        kept = jnp.zeros((self.missing.size, S), self.missing.dtype).at[self.pairs].set(self.kept[k], mode="drop")
        return jnp.where(self.overflow, self.draw(k), kept.reshape(self.missing.shape + (S,)))


def at_eta(state: PSRLContinuousState) -> jax.Array:
    """``[S, A]``: the pairs whose candidates are posterior draws, ``N(s, a) >= eta`` (:class:`Draws`.posterior)."""
    return state.schedule.visits.astype(state.Q.dtype) >= state.constants.eta


def draws(
    key: jax.Array, state: PSRLContinuousState, *, variant: Variant = "paper", keep_limit: int = KEEP_LIMIT,
    lean: bool = False,
) -> Draws:
    """The candidates of one plan (module docstring) without their dense kernels.

    The state receiving the missing mass is one uniform draw (:func:`jaxmdp.sampling.fused_random.uniform_index`)
    over the real states (``state_mask``, in index order, wherever the padding lies) per pair and slot
    (``variant="colosseum"``: per slot, shared by all pairs). The colosseum variant's deviation divides by
    ``max(1, N(s, a, s'))`` and its posterior draws are normalised by ``sum + 1e-5``. ``p^-`` is computed at the
    successor slots only (:class:`Draws`). The posterior draws of the first ``M = min(S A, keep_limit / (max_psi S))``
    (at least one) pairs at ``eta`` are kept (``keep_limit`` floats, static; default :data:`KEEP_LIMIT`), drawn only if
    some pair (of any member of a ``vmap``) is at ``eta``; with more pairs at ``eta``, every backup draws all rows again
    from the same keys (:meth:`Draws.draw`). ``lean`` (static): for a state with no pair at ``eta`` (the caller's
    promise, not checked), keep no rows at all (:attr:`Draws.lean`); the candidates are the same."""
    colosseum = variant == "colosseum"
    hp, c = state.hparams, state.constants
    dtype = state.Q.dtype
    S, A = state.Q.shape
    K = hp.max_psi
    mask = state.state_mask
    n_real = jnp.sum(mask).astype(dtype)
    N = state.schedule.visits.astype(dtype)
    n1 = jnp.maximum(N, 1.0)[..., None]
    log4s = jnp.log(4.0 * n_real)
    succ = state.successors
    p_minus = _p_minus(succ.counts.astype(dtype), n1, log4s, colosseum)
    k_dir, k_z = jax.random.split(key)
    real_states = jnp.argsort(~mask, stable=True)  # the real states first, in index order
    # One written-out hash and a multiply-shift an entry, fused with their use; a remainder by the traced number of
    # real states would run scalar (docs/performance.md, Continuous planning).
    index = fused_random.uniform_index(k_z, (K,) if colosseum else (K, S, A), jnp.sum(mask).astype(jnp.int32))
    z = jnp.broadcast_to(real_states[index].reshape((K, 1, 1) if colosseum else (K, S, A)), (K, S, A))
    posterior = at_eta(state)
    M = 0 if lean else min(S * A, max(1, keep_limit // (K * S)))
    (pairs,) = jnp.nonzero(posterior.reshape(-1), size=M, fill_value=S * A)
    out = Draws(slot_counts=succ.counts, slot_states=succ.states, p_minus=p_minus,
                missing=1.0 - jnp.sum(p_minus, axis=-1), z=z.astype(jnp.int32),
                posterior=posterior, concentration=jnp.stack([1.0 / n_real, c.omega, c.kappa]).astype(dtype),
                state_mask=mask, key=k_dir, active=jnp.arange(K) < c.psi, pairs=pairs.astype(jnp.int32),
                kept=jnp.zeros((K, M, S), dtype), order=succ.order, bandwidth=succ.bandwidth,
                offset=COLOSSEUM_DIRICHLET_OFFSET if colosseum else 0.0, colosseum=colosseum,
                scaled=hp.scaled_dirichlet, lean=lean)
    if lean:
        return out
    zeros = jnp.zeros((M, S), dtype)

    # The draws come in as an operand, so that the concentrations are computed inside the skip, once per plan that
    # draws any.
    def kept(d):
        alpha = d.kept_alpha()
        return jax.lax.map(lambda k: only_if(d.active[k], d.dirichlet, zeros, k, alpha), jnp.arange(K))

    return out.replace(kept=only_if(out.any_posterior, kept, out.kept, out))


def candidate_kernels(
    key: jax.Array, state: PSRLContinuousState, *, variant: Variant = "paper", keep_limit: int = KEEP_LIMIT
) -> jax.Array:
    """The dense ``[max_psi, S, A, S]`` candidate kernels of :func:`draws` (the same draws a plan with this key
    uses; for tests and inspection, a plan never builds them). Slots ``k >= psi`` repeat candidate 0, so they never
    change a maximum over candidates.

    ``variant="colosseum"``: the reference's simple optimistic sampling, whose deviation divides by the per-next-state
    count ``max(1, N(s, a, s'))`` and whose candidate ``k`` hands the missing mass of every pair to one shared state
    ``z_k``; posterior draws are normalised by ``sum + 1e-5``. ``keep_limit``: as for :func:`draws`."""
    d = draws(key, state, variant=variant, keep_limit=keep_limit)
    S = state.Q.shape[0]
    zeros = jnp.zeros(d.missing.shape + (S,), d.missing.dtype)
    p_minus = d.p_minus_dense()

    def one(k):
        posterior = only_if(d.any_posterior, d.posterior_draw, zeros, k)
        optimistic = p_minus + d.missing[..., None] * jax.nn.one_hot(d.z[k], S, dtype=d.missing.dtype)
        return jnp.where(d.posterior[..., None], posterior, optimistic)

    P = jax.lax.map(one, jnp.arange(d.z.shape[0]))
    return jnp.where(d.active[:, None, None, None], P, P[:1])


def extended_mdp(R: jax.Array, P: jax.Array, action_mask: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The extended MDP as a dense model (for tests and inspection; :func:`plan` uses its structure instead): action
    ``j = a * max_psi + k`` of ``s`` has candidate ``k``'s kernel of ``(s, a)`` and reward ``R[s, a]``. Returns
    ``(T[S, A max_psi, S], R[S, A max_psi], action_mask[A max_psi])``; padded actions mirror action 0."""
    K, S, A, _ = P.shape
    R = copy_action_zero(R, action_mask)
    P = jnp.where(action_mask[None, None, :, None], P, P[:, :, :1])
    T = jnp.transpose(P, (1, 2, 0, 3)).reshape(S, A * K, S)
    return T, jnp.repeat(R, K, axis=1), jnp.repeat(action_mask, K)


def colosseum_extended_rewards(R: jax.Array, psi: jax.Array, max_psi: int, action_mask: jax.Array) -> jax.Array:
    """The reference's rewards of the extended actions, ``[S, A max_psi]``: its action ``j = a psi + k`` gets
    ``R[s, j mod A]`` (``A`` real actions), the reward of another real action than the one whose kernel it uses.
    Slots ``k >= psi`` and padded actions repeat ``(a, 0)`` and ``(0, k)``, as :func:`extended_mdp` lays them out."""
    S, A = R.shape
    k = jnp.arange(max_psi)[None, :]
    a = jnp.where(action_mask, jnp.arange(A), 0)[:, None]
    j = a * psi + jnp.where(k < psi, k, 0)
    return R[:, j % jnp.sum(action_mask)].reshape(S, A * max_psi)


def _extended_rewards(R: jax.Array, state: PSRLContinuousState, variant: Variant) -> jax.Array:
    """``[max_psi, S, A]``: the reward of extended action ``(a, k)`` in ``s``, padded actions mirroring action 0."""
    S, A = R.shape
    K = state.hparams.max_psi
    if variant == "colosseum":
        R_ext = colosseum_extended_rewards(R, state.constants.psi, K, state.action_mask).reshape(S, A, K)
        return jnp.transpose(R_ext, (2, 0, 1))
    return jnp.broadcast_to(copy_action_zero(R, state.action_mask), (K, S, A))


def _kept_position(d: Draws, s: jax.Array, a: jax.Array) -> jax.Array:
    """The index ``m`` of pair ``(s, a)`` among the kept pairs ``d.pairs`` (0 for a pair not kept)."""
    A = d.missing.shape[1]
    M = d.pairs.shape[0]
    position = jnp.zeros((d.missing.size,), jnp.int32).at[d.pairs].set(jnp.arange(M, dtype=jnp.int32), mode="drop")
    return position[s * A + a]


def best_candidates(d: Draws, R_ext: jax.Array, V: jax.Array, gamma: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Per pair the best candidate under values ``V``: ``Q[s, a] = max_k R_ext[k, s, a] + gamma row_k(s, a) . V`` and
    its ``k`` (the lowest among ties).

    Optimistic rows cost ``O(S A K)`` for ``p^- . V`` (on the successor slots) and ``O(max_psi S A)`` for ``V[z]``;
    the kept posterior rows ``O(max_psi M S)``. With more than ``M`` pairs at ``eta`` (some member of a ``vmap``), the
    posterior rows of all pairs are drawn again, one slot ``[S, A, S]`` at a time, each slot skipped past ``psi``
    (:func:`_posterior_rows` draws a chosen pair's row again from the same key)."""
    K, S, A = d.z.shape
    M = d.pairs.shape[0]
    dtype = V.dtype
    q_opt = R_ext + gamma * (d.p_minus_dot(V) + d.missing * V[d.z])  # [max_psi, S, A]
    q_opt = jnp.where(d.active[:, None, None], q_opt, -jnp.inf)
    best_opt, k_opt = max_and_first_argmax(q_opt, axis=0)
    if d.lean:  # static: no pair at eta
        return best_opt, k_opt

    pairs = jnp.minimum(d.pairs, S * A - 1)

    def kept_values(V):  # [max_psi, M]; skipped unless some pair is at eta (never at the benchmark's largest sizes)
        q = R_ext.reshape(K, S * A)[:, pairs] + gamma * jnp.sum(d.kept * V, axis=-1)
        return jnp.where(d.active[:, None], q, -jnp.inf)

    q_kept = only_if(d.any_posterior, kept_values, jnp.full((K, M), -jnp.inf, dtype), V)

    def scatter(fill, x):  # [M] values of the kept pairs -> [S, A], fill elsewhere
        return jnp.full((S * A,), fill, x.dtype).at[d.pairs].set(x, mode="drop").reshape(S, A)

    q_post = scatter(-jnp.inf, jnp.max(q_kept, axis=0))
    k_post = scatter(0, jnp.argmax(q_kept, axis=0).astype(jnp.int32))

    if M < S * A:  # static: some pairs' draws may not be kept

        # The draws come into each skip as an operand (``dd``), not by closure: closed over, the work of the
        # Dirichlet sampler that depends on the counts alone (dense, [S, A, S]) was hoisted out of every loop and ran
        # at every plan, skipped or not (docs/performance.md, Continuous planning).
        def all_slots(c, dd, V):
            def better(carry, k):
                q, kk = carry
                q_k = R_ext[k] + gamma * jnp.sum(dd.draw(k) * V, axis=-1)
                up = q_k > q
                return jnp.where(up, q_k, q), jnp.where(up, k, kk)

            return jax.lax.fori_loop(0, K, lambda k, c: jax.lax.cond(dd.active[k], better, lambda c, _: c, c, k), c)

        # One skip around the whole loop, and no [S, A, S] in its carry: carried through a skip per slot, the rows
        # were copied at every slot of every backup (docs/performance.md, Continuous planning).
        init = (jnp.full((S, A), -jnp.inf, dtype), jnp.zeros((S, A), jnp.int32))
        q_all, k_all = only_if(d.overflow, all_slots, init, init, d, V)
        q_post, k_post = jnp.where(d.overflow, q_all, q_post), jnp.where(d.overflow, k_all, k_post)

    return jnp.where(d.posterior, q_post, best_opt), jnp.where(d.posterior, k_post, k_opt)


def _posterior_rows(d: Draws, s: jax.Array, a: jax.Array, k: jax.Array) -> jax.Array:
    """The posterior rows ``[n, S]`` of candidates ``k[n]`` of pairs ``(s[n], a[n])`` at ``eta``: kept, or, with more
    pairs at ``eta`` than kept (``overflow``), drawn again from the same keys (the rows :func:`best_candidates`
    compared)."""
    rows = d.kept[k, _kept_position(d, s, a)]
    K, S, A = d.z.shape
    if d.pairs.shape[0] >= S * A:  # static: every pair's draws are kept
        return rows

    def redraw(s, a, k, rows, dd):
        pick = lambda j, r: jnp.where((k == j)[:, None], dd.draw(j)[s, a], r)  # noqa: E731
        return jax.lax.fori_loop(0, K, pick, rows)

    return only_if(d.overflow, redraw, rows, s, a, k, rows, d)


# Above this many states, a policy's evaluation first eliminates the states whose chosen row is a jump (a simple
# optimistic candidate with all its mass missing, p^- = 0: every row of a pair visited fewer than about 3 ln(4 S)
# times), solving for the other states and the states jumped to only (dp.discounted_jump_chain_values), if they are at
# most this many; else (or with fewer states) the whole [S, S] system. At 948 states after 2 000 or 20 000 random
# steps every chosen row was a jump, to 41-49 distinct states.
# The elimination tries a system of 64 states first: a solve's pivots are applied by a loop of one step per row
# (jax.lax.linalg.lu on a CPU), so the system's size, not the states it holds, sets its cost (docs/performance.md,
# Continuous planning).
JUMP_STATES = (64, 256)
# With the MDP's band order (the runner's spec gives it on a CPU), an evaluation that the eliminations cannot take
# (late in a run, most chosen rows carry observed mass) is a banded elimination corrected for the states jumped to, if
# they are at most this many (tried in increasing order), before the whole [S, S] system. The eliminations go first:
# where they fit (every row but a few hundred a jump) they cost 0.2-1.5 ms at 948 states, the banded one 5-16 ms.
# A chosen row's jump goes to its best of psi candidate states, so few states receive them: 38-53 at 784-820 states
# after 150 000-250 000 steps of the agent's own play, where a plan became 5-8x faster (docs/performance.md,
# Continuous planning).
BAND_TARGETS = (64, 256)


class _Choice(struct.PyTreeNode):
    """A deterministic policy of the extended MDP, per state: real action, candidate, reward. Its kernel rows are
    built only where needed (:func:`_chosen_rows`): held as ``[S, S]`` rows, the policy's choice, carry and backups
    cost ``O(S^2)`` per policy-iteration step, several times the structured backup itself."""

    action: jax.Array  # [S] int32
    k: jax.Array  # [S] int32: the candidate slot of the chosen pair
    reward: jax.Array  # [S]
    jump: jax.Array  # [S] int32: the state a row moves to with probability 1 (all its mass missing), else -1


def _chosen_rows(d: Draws, pi: _Choice, s: jax.Array) -> jax.Array:
    """The kernel rows ``[n, S]`` that policy ``pi`` chooses at states ``s[n]``: ``p^-(s, a) + missing(s, a)
    e_z[k, s, a]``, or the pair's posterior row ``k`` at ``eta``."""
    S = d.state_mask.shape[0]
    a, k = pi.action[s], pi.k[s]
    jumps = jax.nn.one_hot(d.z[k, s, a], S, dtype=d.missing.dtype)
    optimistic = d.p_minus_rows(s, a) + d.missing[s, a][:, None] * jumps
    if d.lean:  # static
        return optimistic
    posterior = only_if(d.any_posterior, _posterior_rows, jnp.zeros_like(optimistic), d, s, a, k)
    return jnp.where(d.posterior[s, a][:, None], posterior, optimistic)


def _chosen_expectations(d: Draws, pi: _Choice, V: jax.Array) -> jax.Array:
    """``row(s) . V`` for every state's chosen row: for optimistic rows ``p^- . V`` (:meth:`Draws.p_minus_dot`, the
    expression of the improvement step's backup at the same ``V``) plus the jump's value, the kept posterior rows'
    ``O(max_psi M S)`` when some pair is at ``eta``, and every chosen row (:func:`_chosen_rows`) only with more pairs at
    ``eta`` than kept."""
    K, S, A = d.z.shape
    s, a, k = jnp.arange(S), pi.action, pi.k
    optimistic = d.p_minus_dot(V)[s, a] + d.missing[s, a] * V[d.z[k, s, a]]
    if d.lean:  # static
        return optimistic

    def kept(dd, V):
        return jnp.sum(dd.kept * V, axis=-1)[k, _kept_position(dd, s, a)]

    posterior = only_if(d.any_posterior, kept, jnp.zeros_like(V), d, V)
    if d.pairs.shape[0] < S * A:  # static
        every = lambda dd, V: jnp.sum(_chosen_rows(dd, pi, s) * V, axis=-1)  # noqa: E731
        posterior = only_if(d.overflow, every, posterior, d, V)
    return jnp.where(d.posterior[s, a], posterior, optimistic)


def _banded_values(d: Draws, pi: _Choice, gamma: jax.Array, size: int) -> tuple[jax.Array, jax.Array]:
    """``(V, fits)``: policy ``pi``'s values by a banded elimination in the MDP's band order (``d.order``, within
    which every ``p^-`` must lie: the caller checks :meth:`Draws.p_minus_kernel`'s ``in_band``), the jumps of the
    missing mass as a rank-``m`` correction over the ``m <= size`` (static) states jumped to
    (:func:`jaxmdp.dynamic_programming.discounted_banded_jump_chain_values`). ``fits``: ``m <= size`` and no chosen
    row a posterior one."""
    order, pos = d.order, em.positions(d.order)
    a, k = pi.action[order], pi.k[order]  # position i: state order[i]
    # The chosen rows' p^- in the order's positions: a deterministic policy's successor_policy_matrix.
    B = dp.successor_policy_matrix(pos[d.slot_states[order, a]][:, None], d.p_minus[order, a][:, None],
                                   jnp.ones((order.shape[0], 1), d.p_minus.dtype))
    V, fits = dp.discounted_banded_jump_chain_values(
        B, d.missing[order, a], pos[d.z[k, order, a]], pi.reward[order], gamma, d.bandwidth, size)
    if not d.lean:  # static
        fits = fits & ~jnp.any(d.posterior[order, a])
    return V[pos], fits


def _greedy(
    d: Draws, R_ext: jax.Array, V: jax.Array, gamma: jax.Array, action_mask: jax.Array
) -> tuple[jax.Array, _Choice]:
    """One improvement step: ``Q[S, A] = max_k Q_ext(s, (a, k))`` (padded actions mirroring action 0) and the greedy
    extended action per state (lowest real action, then lowest candidate, among ties) as a :class:`_Choice`."""
    q, k = best_candidates(d, R_ext, V, gamma)
    q = copy_action_zero(q, action_mask)
    S = q.shape[0]
    s = jnp.arange(S)
    a = dp.greedy_actions(q, action_mask)
    ka = k[s, a]
    no_mass = jnp.all(d.p_minus[s, a] == 0, axis=-1)
    jump = jnp.where(~d.posterior[s, a] & no_mass, d.z[ka, s, a], -1)
    return q, _Choice(action=a, k=ka, reward=R_ext[ka, s, a], jump=jump)


def extended_policy_iteration(
    d: Draws, R_ext: jax.Array, gamma: jax.Array, V0: jax.Array, action_mask: jax.Array,
    jump_states: int | tuple[int, ...] = JUMP_STATES, band_targets: int | tuple[int, ...] = BAND_TARGETS,
) -> dp.ValueIterationResult:
    """Policy iteration (:func:`jaxmdp.dynamic_programming.policy_iteration_by`, exact evaluation, ``rtol = 1e-5``)
    on the extended MDP of ``d`` and rewards ``R_ext[max_psi, S, A]``, from the policy greedy on one backup of
    ``V0``. Improvement picks per pair the best candidate and per state the best real action (:func:`_greedy`);
    evaluation solves ``(I - gamma P_pi) V = r_pi`` for the chosen rows, with more states than the largest of
    ``jump_states`` (static sizes, tried in increasing order) first eliminating those whose chosen row is a jump
    (:data:`JUMP_STATES`), building the rows of the other states only; then, with the MDP's band order in ``d``, a
    banded elimination corrected for at most ``band_targets`` states jumped to (:data:`BAND_TARGETS`,
    :func:`_banded_values`); then the whole chain. ``Q[S, A] = max_k Q_ext(s, (a, k))``."""
    sizes = sorted({jump_states} if isinstance(jump_states, int) else set(jump_states))
    band_sizes = sorted({band_targets} if isinstance(band_targets, int) else set(band_targets))
    S = V0.shape[0]

    def dense(pi, dd):  # dd: the draws as an operand, so that a skipped evaluation's rows are not built anyway
        return dp.discounted_chain_values(_chosen_rows(dd, pi, jnp.arange(S)), pi.reward, gamma)

    def eliminated(size):
        def values(pi, dd):
            return dp.discounted_jump_chain_values(lambda s: _chosen_rows(dd, pi, s), pi.reward, gamma, pi.jump, size)

        return values

    def banded(size):
        return lambda pi, dd: _banded_values(dd, pi, gamma, size)

    # Once per plan, for every evaluation: the observed successors lie in the MDP's band (False only for a wrong order).
    in_band = d.p_minus_kernel().in_band()

    def evaluate(pi):
        if S <= sizes[-1]:  # static
            return dense(pi, d)
        V, fits = eliminated(sizes[0])(pi, d)
        for size in sizes[1:]:
            V, fits = only_if(~fits, eliminated(size), (V, fits), pi, d)
        if d.order is not None:  # static: the MDP's band order is known
            for size in band_sizes:
                V, fits = only_if(~fits & in_band, banded(size), (V, fits), pi, d)
        return only_if(~fits, dense, V, pi, d)

    def improve(pi, V):
        q, proposal = _greedy(d, R_ext, V, gamma, action_mask)
        current = pi.reward + gamma * _chosen_expectations(d, pi, V)
        return q, jnp.max(jnp.where(action_mask, q, -jnp.inf), axis=-1) - current, proposal

    return dp.policy_iteration_by(evaluate, improve, _greedy(d, R_ext, V0, gamma, action_mask)[1])


def extended_draws(
    key: jax.Array,
    state: PSRLContinuousState,
    *,
    variant: Variant = "paper",
    reward_variant: Variant | None = None,
    keep_limit: int = KEEP_LIMIT,
    lean: bool = False,
) -> tuple[jax.Array, Draws]:
    """The extended MDP that :func:`agents.psrl_continuous.plan` draws with ``key``: its rewards
    ``R_ext[max_psi, S, A]`` (one Normal-Gamma draw per pair, :func:`_extended_rewards`) and its candidates
    (:func:`draws`, ``lean`` as there)."""
    k_r, k_p = jax.random.split(key)
    R_ext = _extended_rewards(normal_gamma_sample(k_r, state.rewards), state, reward_variant or variant)
    return R_ext, draws(k_p, state, variant=variant, keep_limit=keep_limit, lean=lean)
