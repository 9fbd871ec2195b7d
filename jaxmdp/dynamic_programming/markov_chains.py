"""Markov reward chains (paper §2.1, average reward): recurrent classes, the Cesàro limit ``P*``, the gain ``g = P* r``
by Grassmann-Taksar-Heyman elimination (:mod:`jaxmdp.gth`) and the bias.

The gain is computed by GTH elimination, not by a linear solve with ``I - P``, because the elimination only adds
non-negative numbers and so stays accurate however slowly the chain mixes, where the solve loses digits in proportion
to the mixing time. The pass-down and back-substitution after an elimination (``_pass_down``,
``_substitute_up``) serve the discounted banded solve as well
(:func:`~jaxmdp.dynamic_programming.discounted_chain_values_banded`).
"""

from __future__ import annotations

from collections.abc import Callable

import chex
import jax
import jax.numpy as jnp

from jaxmdp._asserts import assert_chain
from jaxmdp.dynamic_programming.backups import compiled
from jaxmdp.gth import BAND_BLOCK, GTH_BLOCK, gth_eliminate, gth_eliminate_banded
from jaxmdp.gth import bandwidth as gth_bandwidth
from jaxmdp.jaxlib_workarounds.linalg import solve as linear_solve

__all__ = ["recurrent_classes", "successor_reachability", "chain_gain", "chain_bias", "cesaro_limit"]


def _classes_from_reach(reach: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``(recurrent, same_class)`` of a reflexive-transitive reachability matrix: a state is recurrent when every
    state it reaches reaches it back."""
    recurrent = jnp.all(~reach | reach.T, axis=1)
    same_class = reach & reach.T & recurrent[:, None] & recurrent[None, :]
    return recurrent, same_class


@compiled()
def recurrent_classes(P: jax.Array, reach: jax.Array | None = None) -> tuple[jax.Array, jax.Array]:
    """Recurrent states of a stochastic matrix and its closed classes.

    Reachability comes from repeated squaring of the boolean adjacency (``O(S^3 log S)``, exact), unless ``reach``
    (``[S, S]`` bool, reflexive and transitive, e.g. from :func:`successor_reachability`) is given. A state is
    recurrent when every state it reaches reaches it back. Returns ``(recurrent[S], same_class[S, S])`` with
    ``same_class[s, t]`` true iff ``s`` and ``t`` are recurrent and in the same class.
    """
    S = assert_chain(P)
    if reach is not None:
        chex.assert_shape(reach, (S, S), custom_message="reach: reachability [S, S]")
        chex.assert_type(reach, bool, custom_message="reach: reachability")
    if reach is None:
        S = P.shape[0]
        reach = ((P > 0) | jnp.eye(S, dtype=bool)).astype(P.dtype)
        n_squarings = max(1, (S - 1).bit_length())
        reach = jax.lax.fori_loop(0, n_squarings, lambda _, M: jnp.minimum(M @ M, 1.0), reach) > 0
    return _classes_from_reach(reach)


@compiled()
def successor_reachability(succ: jax.Array, edge: jax.Array) -> jax.Array:
    """``reach[s, t]``: whether ``t`` is reachable from ``s`` in zero or more steps along the successor slots
    ``s -> succ[s, ...]`` whose ``edge[s, ...]`` is true (e.g. ``pi(a|s) p(s, a, k) > 0``); ``[S, S]`` bool.

    Rows are bit sets (32 states a ``uint32`` word) and ``reach[s] |= reach[t]`` over the edges ``s -> t`` is swept
    until nothing changes: ``O(S^2 K / 32)`` word operations a sweep, and as many sweeps as the longest shortest path
    plus one (no dense ``S x S`` products; :func:`recurrent_classes` squares the dense adjacency instead).
    """
    chex.assert_type([succ, edge], [int, bool], custom_message="succ: state indices, edge: boolean")
    chex.assert_equal_shape([succ, edge], custom_message="succ and edge: [S, ...] slots")
    S = succ.shape[0]
    states = jnp.arange(S)
    nbr = jnp.where(edge, succ, states.reshape((S,) + (1,) * (succ.ndim - 1))).reshape(S, -1)
    n_words = (S + 31) // 32
    word, bit = states // 32, (states % 32).astype(jnp.uint32)
    R = jnp.zeros((S, n_words), jnp.uint32).at[states, word].set(jnp.left_shift(jnp.uint32(1), bit))

    def body(c):
        R, _ = c
        R2 = R | jax.lax.reduce(R[nbr], jnp.uint32(0), jax.lax.bitwise_or, (1,))
        return R2, jnp.any(R2 != R)

    R = jax.lax.while_loop(lambda c: c[1], body, (R, jnp.asarray(True)))[0]
    return (jnp.right_shift(R[:, word], bit[None, :]) & jnp.uint32(1)) > 0


@compiled("block", "bandwidth")
def chain_gain(
    P: jax.Array,
    r: jax.Array,
    reach: jax.Array | None = None,
    block: int = GTH_BLOCK,
    order: jax.Array | None = None,
    bandwidth: int | None = None,
) -> jax.Array:
    """Long-run average reward ``g = P* r`` of a Markov chain from every state (``P*`` the Cesàro limit).

    Uses Grassmann-Taksar-Heyman elimination (:func:`jaxmdp.gth.gth_eliminate`, blocked: ``block`` states at a time,
    the trailing updates as matrix products), which only adds non-negative numbers and so stays accurate however
    slowly the chain mixes (a linear solve with ``I - P`` loses digits in proportion to the mixing time). States are
    ordered recurrent first and transient last; eliminating from the last position down, a recurrent state with no
    mass left towards lower positions is the root of its class. Back-substitution gives every class's stationary
    distribution (hence its gain; each class is renormalised on the fly to stay inside the floating-point range), and
    transient states average the gains they are absorbed into. ``O(S^3)`` plus the reachability of
    :func:`recurrent_classes` (or none, given ``reach``: ``P``'s reflexive-transitive reachability as there); handles
    periodic and multichain matrices. ``block = 1`` is the scalar elimination (larger blocks sum the same terms in
    another order).

    Banded (``order``, ``[S]``, a permutation of the states, and a static ``bandwidth``, e.g. from
    :func:`jaxmdp.gth.band_order`): the recurrent states come first and the transient ones last, each in ``order``'s
    order, and a transient state's mass into the recurrent states is one "absorbed" number (no recurrent state leads
    to a transient one). If then every transition joins positions at most ``bandwidth`` apart (checked, ``O(S^2)``),
    both parts are eliminated in one banded pass (:func:`jaxmdp.gth.gth_eliminate_banded`, ``O(S w^2)``), and a
    transient state's gain adds ``c_k``, the recurrent gains it moves to, carried down the elimination like its
    absorbed mass. Otherwise the dense elimination runs (a ``lax.cond``: use it per chain, not under ``vmap``).
    """
    if (order is None) != (bandwidth is None):
        raise ValueError("order and bandwidth go together: give both (jaxmdp.gth.band_order) or neither")
    S = assert_chain(P)
    chex.assert_shape(r, (S,), custom_message="r: rewards [S]")
    if order is not None:
        chex.assert_shape(order, (S,), custom_message="order: a permutation of the states [S]")
    recurrent, same_class = recurrent_classes(P, reach)
    perm = _recurrent_first(jnp.arange(S) if order is None else order, recurrent)
    Pp, rec = P[perm][:, perm], recurrent[perm]
    args = (Pp, r[perm], rec, jnp.argmax(same_class, axis=1)[perm])
    if order is None:
        g = _gain_after_elimination(*args, block, None)
    else:
        fits = gth_bandwidth(jnp.where(~rec[:, None] & rec[None, :], 0.0, Pp)) <= bandwidth
        g = jax.lax.cond(
            fits, lambda: _gain_after_elimination(*args, BAND_BLOCK, bandwidth),
            lambda: _gain_after_elimination(*args, block, None),
        )
    return jnp.zeros((S,), P.dtype).at[perm].set(g)


def _recurrent_first(order: jax.Array, recurrent: jax.Array) -> jax.Array:
    """``order`` with its recurrent states first and its transient ones last, each in ``order``'s order."""
    return order[jnp.argsort(~recurrent[order], stable=True)]


def _window(x: jax.Array, k: jax.Array, width: int) -> tuple[jax.Array, jax.Array]:
    """The ``width`` entries of ``x`` (leading axis) from position ``max(k - width, 0)`` and a mask of those below
    ``k``: every position in ``[k - width, k)`` is among them."""
    start = jnp.maximum(k - width, 0)
    return jax.lax.dynamic_slice_in_dim(x, start, width), start + jnp.arange(width) < k


def _column_window(M: jax.Array, k: jax.Array, width: int) -> jax.Array:
    """Column ``k`` of ``M`` at the rows of :func:`_window`."""
    return jax.lax.dynamic_slice(M, (jnp.maximum(k - width, 0), k), (width, 1))[:, 0]


def _gain_after_elimination(
    P: jax.Array, r: jax.Array, rec: jax.Array, label: jax.Array, block: int, bandwidth: int | None,
    absorbed: tuple[jax.Array, Callable[[jax.Array], jax.Array]] | None = None,
) -> jax.Array:
    """:func:`chain_gain` of a chain whose recurrent states (``rec``) come first; ``label`` is the same for the states
    of a recurrent class. Banded (:func:`jaxmdp.gth.gth_eliminate_banded`) when ``bandwidth`` is given: then every
    transition other than from a transient to a recurrent state must join positions at most ``bandwidth`` apart.
    ``absorbed`` (banded only): ``P`` already without a transient state's moves into recurrent ones, given instead as
    their mass per state and a function of the recurrent gains ``g`` giving ``sum_j P[k, j] g_j`` over them (from
    successor lists: no ``S x S`` pass). A chain without transient states skips the transient part (two ``S``-step
    loops).

    Back-substitution reads only the ``w`` positions below each state (``w`` the bandwidth, else ``S``). The
    stationary masses can span more than float32's range within a class (ratios of 1e46 on a 50-state chain), so each
    is kept as a mantissa and a power-of-two exponent (``frexp``): a new mass sums its terms scaled by the largest
    term's power of two, and a class's masses are brought to its largest exponent before its gain is taken (scaling by
    a power of two is exact)."""
    S = P.shape[0]
    dtype = P.dtype
    W = S if bandwidth is None else min(max(bandwidth, 1), S)
    if bandwidth is None:
        M, scale = gth_eliminate(P, block)
    else:
        if absorbed is None:  # a transient state's moves into the recurrent ones: one absorbed mass
            into = ~rec[:, None] & rec[None, :]
            P_into, P = jnp.where(into, P, 0.0), jnp.where(into, 0.0, P)
            absorbed = jnp.sum(P_into, axis=1), lambda g: P_into @ g
        M, scale = gth_eliminate_banded(P, absorbed[0], bandwidth, block)
    root = rec & (scale == 0)
    lowest = jnp.iinfo(jnp.int32).min

    def stationary(k, me):
        mant, expo = me
        m, below = _window(mant, k, W)
        e, _ = _window(expo, k, W)
        col = _column_window(M, k, W)
        tm, te = jnp.frexp(m * col)  # each term mant * col = tm 2^te, times 2^e
        te = jnp.where(below & (tm > 0), te + e, lowest)
        top = jnp.max(te)
        val = jnp.sum(jnp.where(te > lowest, jnp.ldexp(tm, te - top), 0.0))
        vm, ve = jnp.frexp(val)
        vm = jnp.where(root[k], 0.5, jnp.where(rec[k], vm, 0.0))
        ve = jnp.where(root[k], 1, jnp.where(rec[k] & (val > 0), ve + top, 0))
        return mant.at[k].set(vm), expo.at[k].set(ve)

    mant, expo = jax.lax.fori_loop(0, S, stationary, (jnp.zeros((S,), dtype), jnp.zeros((S,), jnp.int32)))
    # Every class's masses on its largest exponent; class sums by label.
    mass = rec & (mant > 0)
    top = jax.ops.segment_max(jnp.where(mass, expo, lowest), label, num_segments=S)
    pi = jnp.where(mass, jnp.ldexp(mant, expo - top[label]), 0.0)
    num = jax.ops.segment_sum(pi * r, label, num_segments=S)
    den = jax.ops.segment_sum(pi, label, num_segments=S)
    g = jnp.where(rec, num[label] / jnp.where(rec, den[label], 1.0), 0.0)

    def transient(g: jax.Array) -> jax.Array:
        # c_k: the recurrent gains that transient k moves to, passed down like its absorbed mass (banded; densely,
        # the rows keep their recurrent columns).
        c_k = jnp.zeros((S,), dtype) if bandwidth is None else _pass_down(M, absorbed[1](g)[:, None], W)[:, 0]
        return _substitute_up(M, scale, c_k[:, None], g[:, None], rec, W)[:, 0]

    return jax.lax.cond(jnp.all(rec), lambda g: g, transient, g)


def _pass_down(M: jax.Array, c: jax.Array, width: int) -> jax.Array:
    """Columns ``c[S, m]`` carried down a (GTH) elimination whose stored columns ``col_k`` are in ``M`` (positions
    within ``width`` above the diagonal): ``c_i += col_k[i] c_k`` for ``i < k``, as ``k`` is eliminated, last position
    first. An absorbed mass, or a reward, passed on to the positions that remain."""
    S = M.shape[0]

    def step(t, c):
        k = S - 1 - t
        part, below = _window(c, k, width)
        col = jnp.where(below, _column_window(M, k, width), 0.0)
        return jax.lax.dynamic_update_slice_in_dim(c, part + col[:, None] * c[k][None, :], jnp.maximum(k - width, 0), 0)

    return jax.lax.fori_loop(0, S, step, c)


def _substitute_up(
    M: jax.Array, scale: jax.Array, c: jax.Array, x: jax.Array, fixed: jax.Array, width: int
) -> jax.Array:
    """Back-substitution after a (GTH) elimination, first position first: ``x_k = (sum_{j<k} M[k, j] x_j + c_k) /
    scale_k`` (the eliminated rows ``M[k, :k]``, within ``width`` below the diagonal; ``scale_k`` the mass leaving
    ``k`` downwards), for every ``k`` but the ``fixed`` ones, which keep ``x_k``. ``c``, ``x``: ``[S, m]``."""

    def step(k, x):
        part, below = _window(x, k, width)
        row = jnp.where(below, jax.lax.dynamic_slice(M, (k, jnp.maximum(k - width, 0)), (1, width))[0], 0.0)
        new = (jnp.sum(row[:, None] * part, axis=0) + c[k]) / jnp.where(scale[k] > 0, scale[k], 1.0)
        return x.at[k].set(jnp.where(fixed[k], x[k], new))

    return jax.lax.fori_loop(0, M.shape[0], step, x)


@compiled("n_squarings")
def chain_bias(P: jax.Array, r: jax.Array, n_squarings: int = 48) -> jax.Array:
    """Exact bias ``h = (I - P + P*)^{-1} (r - P* r)`` of a Markov chain ``P`` with rewards ``r``; ``P* h = 0``.

    ``P* = lim (I + P)^n / 2^n`` is the Cesàro limit (the lazy chain is aperiodic with the same limit), taken by
    ``n_squarings`` squarings (48: ``2^48`` steps, each renormalised to stay stochastic); the bias then solves
    Puterman 1994 Thm. A.7. Dense ``O(S^3)``; :func:`chain_gain` is the accurate route to the gain ``P* r`` alone.
    """
    chex.assert_shape(r, (assert_chain(P),), custom_message="r: rewards [S]")
    eye = jnp.eye(P.shape[0], dtype=P.dtype)
    Pstar = cesaro_limit(P, n_squarings)
    g = Pstar @ r
    return linear_solve(eye - P + Pstar, r - g)


@compiled("n_squarings")
def cesaro_limit(P: jax.Array, n_squarings: int = 48) -> jax.Array:
    """``P* = lim_n (1/n) sum_{t<n} P^t``, taken as ``((I + P) / 2)^(2^n_squarings)`` (the lazy chain is aperiodic with
    the same limit; Puterman 1994 App. A.4), each square renormalised to stay stochastic. Dense ``O(S^3 n)``;
    periodic and multichain matrices alike."""
    assert_chain(P)
    eye = jnp.eye(P.shape[0], dtype=P.dtype)

    def square(_, M):
        M = M @ M
        return M / jnp.sum(M, axis=1, keepdims=True)

    return jax.lax.fori_loop(0, n_squarings, square, 0.5 * (eye + P))

