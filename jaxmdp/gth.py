"""Grassmann-Taksar-Heyman (GTH) elimination of a Markov chain, dense and banded, and the state order that makes the
chains of a sparse MDP banded.

GTH elimination (Grassmann, Taksar & Heyman 1985) censors a chain to fewer and fewer states using only additions,
multiplications and divisions of non-negative numbers, so every entry keeps a small relative error however slowly the
chain mixes. :func:`~jaxmdp.dynamic_programming.chain_gain` builds the gain ``P* r`` on it (paper §2.1, average
reward). The dense elimination costs ``O(S^3)``. The benchmark's chains are sparse (at most ``K`` successors a state,
grids and rivers): in the reverse Cuthill-McKee order of the MDP's successor graph every transition joins states at
most ``w`` positions apart, ``w`` from 1 (RiverSwim) to 105 (a 948-state MiniGridRooms) where ``S`` is up to 948.
Elimination from the last position down never creates an entry outside that band, so :func:`gth_eliminate_banded`
costs ``O(S w^2)``.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse
from scipy.sparse.csgraph import reverse_cuthill_mckee

from jaxmdp.mdp import MDP

__all__ = ["GTH_BLOCK", "BAND_BLOCK", "gth_eliminate", "gth_eliminate_banded", "BandOrder", "band_order", "bandwidth"]

#: States per block of :func:`gth_eliminate`, and the stages whose shrinking leading windows its block loop runs on:
#: the fastest settings of the exact gains (docs/performance.md, Continuous indicators).
GTH_BLOCK = 32
_GTH_STAGES = 4
#: States per block of :func:`gth_eliminate_banded`: the fastest setting of the banded gains (docs/performance.md,
#: Continuous indicators).
BAND_BLOCK = 16

_dot = functools.partial(jnp.matmul, precision=jax.lax.Precision.HIGHEST)


def _block_steps(A: jax.Array, rows: jax.Array, cols: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """The scalar GTH steps that eliminate the positions of one block, last first.

    ``A`` is the ``b x b`` block, ``rows`` its rows on the positions ``F`` that stay (``[b, |F|]``) and ``cols`` its
    columns on ``F`` (``[|F|, b]``). Eliminating block position ``i``: ``s`` is the mass its row sends to the block's
    lower positions and to ``F``; ``col = A[:i, i] / s`` and ``col_f = cols[:, i] / s`` (0 when ``s = 0``); the block's
    lower rows gain ``outer(col, row_i)`` (on the block and on ``F``), the columns on ``F`` gain ``outer(col_f,
    A[i, :i])``, and ``col``, ``col_f`` are stored in column ``i``. Returns ``(A, rows, cols, s)``; the ``F x F``
    part receives ``cols @ rows`` (the caller's matrix product)."""
    b = A.shape[0]
    loc = jnp.arange(b)

    def step(t, small):
        A, rows, cols, s_b = small
        i = b - 1 - t
        lower = loc < i
        row = jnp.where(lower, A[i], 0.0)
        s = jnp.sum(row) + jnp.sum(rows[i])
        divisor = jnp.where(s > 0, s, 1.0)
        col = jnp.where(lower & (s > 0), A[:, i] / divisor, 0.0)
        col_f = jnp.where(s > 0, cols[:, i] / divisor, 0.0)
        A = (A + jnp.outer(col, row)).at[:, i].set(jnp.where(lower, col, A[:, i]))
        rows = rows + jnp.outer(col, rows[i])  # rows i' < i of the block, on F
        cols = (cols + jnp.outer(col_f, row)).at[:, i].set(col_f)  # columns i' < i on F; column i normalised
        return A, rows, cols, s_b.at[i].set(s)

    return jax.lax.fori_loop(0, b, step, (A, rows, cols, jnp.zeros((b,), A.dtype)))


def gth_eliminate(M: jax.Array, block: int = GTH_BLOCK, stages: int = _GTH_STAGES) -> tuple[jax.Array, jax.Array]:
    """GTH elimination of positions ``S-1, ..., 1`` of a non-negative ``M``, ``block`` at a time.

    Eliminating position ``k`` censors the chain to positions ``< k``: with the row ``row_k = M[k, :k]`` and its sum
    ``s_k`` (the mass leaving ``k`` downwards, summed from the off-diagonal entries, never taken as ``1 - M[k, k]``),
    ``M[:k, :k] += outer(col_k, row_k)`` where ``col_k = M[:k, k] / s_k``. Returns ``M`` with ``col_k`` stored in
    column ``k`` above the diagonal and ``row_k`` left in row ``k``, and ``scale[k] = s_k`` (0 when no mass leaves
    downwards; then ``col_k = 0``).

    Blocked: eliminating a block ``B`` of ``b`` positions leaves the stochastic complement ``M_FF + M_FB (I -
    M_BB)^{-1} M_BF`` on the positions ``F`` below it (Meyer 1989, "Stochastic complementation, uncoupling Markov
    chains, and the theory of nearly reducible systems", SIAM Rev. 31; GTH and block elimination: Stewart 1994,
    "Introduction to the Numerical Solution of Markov Chains", ch. 2). The scalar steps (:func:`_block_steps`) update
    only the ``b x b`` block and its panels on ``F``, so these hold exactly the scalar algorithm's numbers; the ``F x
    F`` part only receives, and the block's ``b`` rank-one updates of it are summed as one product ``col[F] row[F]``
    at matrix-multiply speed. (Carrying ``b x b`` coefficient matrices instead of the panels, products of up to ``b``
    factors ``1 / s_k``, overflows float32 on chains that drift towards higher positions: RiverSwim's optimal chain.)
    The blocks run in ``stages`` loops, each on the leading window that its blocks still touch (4 stages do about half
    the flops of one window of size ``S``). ``M`` is padded at the end to whole blocks with zero rows and columns,
    which eliminate to nothing. Products use ``Precision.HIGHEST`` (no reduced-precision float32 products on GPUs).
    ``O(S^3)`` flops, ``S`` sequential steps on ``b x |F|`` panels.
    """
    if block < 1 or stages < 1:
        raise ValueError(f"block and stages must be at least 1, got block={block}, stages={stages}")
    S = M.shape[0]
    b = max(1, min(block, S))
    n_blocks = -(-S // b)
    Sp = n_blocks * b
    M = jnp.pad(M, ((0, Sp - S), (0, Sp - S)))

    def eliminate_block(W, j, carry):
        M, scale = carry  # the leading W x W window
        k0 = W - (j + 1) * b
        rest = jnp.arange(W) < k0
        old_rows, old_cols = jax.lax.dynamic_slice(M, (k0, 0), (b, W)), jax.lax.dynamic_slice(M, (0, k0), (W, b))
        rows, cols = jnp.where(rest[None, :], old_rows, 0.0), jnp.where(rest[:, None], old_cols, 0.0)
        A, rows, cols, s_b = _block_steps(jax.lax.dynamic_slice(M, (k0, k0), (b, b)), rows, cols)
        M = M + _dot(cols, rows)  # only F x F: rows and cols vanish outside F
        M = jax.lax.dynamic_update_slice(M, jnp.where(rest[None, :], rows, old_rows), (k0, 0))
        M = jax.lax.dynamic_update_slice(M, jnp.where(rest[:, None], cols, old_cols), (0, k0))
        M = jax.lax.dynamic_update_slice(M, A, (k0, k0))
        return M, jax.lax.dynamic_update_slice(scale, s_b, (k0,))

    scale = jnp.zeros((Sp,), M.dtype)
    first = 0
    for q in range(min(stages, n_blocks)):
        last = round(n_blocks * (q + 1) / min(stages, n_blocks))
        W = Sp - first * b  # the blocks first..last-1 only touch positions < W
        window = jax.lax.fori_loop(0, last - first, functools.partial(eliminate_block, W), (M[:W, :W], scale[:W]))
        M, scale, first = M.at[:W, :W].set(window[0]), scale.at[:W].set(window[1]), last
    return M[:S, :S], scale[:S]


def gth_eliminate_banded(
    M: jax.Array, out: jax.Array, bandwidth: int, block: int = BAND_BLOCK
) -> tuple[jax.Array, jax.Array]:
    """:func:`gth_eliminate` of a banded ``M`` whose states may also leave to an absorbing set below position 0.

    ``M[i, j]`` must vanish where ``|i - j| > bandwidth`` (static); ``out[k] >= 0`` is the mass that position ``k``
    sends to the absorbing set, which is never eliminated (it counts in ``s_k``, and eliminating ``k`` passes
    ``col_k out[k]`` on to the positions below). Eliminating ``k`` adds ``outer(col_k, row_k)`` on positions within
    ``bandwidth`` below ``k``, so the band holds at every step and each block of ``b`` positions is eliminated in the
    window of the ``w = bandwidth`` positions below it: the scalar steps on ``b x (w + 1)`` and ``w x b`` panels and
    one ``[w, b] x [b, w + 1]`` product, ``O(S w (w + b))`` flops in all instead of ``O(S^3)``. The window is read
    from ``M`` padded with ``w`` zero states in front. Returns ``(M, scale)`` as :func:`gth_eliminate` (with
    ``out`` counted in ``scale``). Entries outside the band must be zero, and the caller must check the band (see
    :func:`bandwidth`): the windows read entries up to ``w + b - 1`` positions apart, so an entry outside the band is
    either dropped or eliminated wrongly, never an error.
    """
    if block < 1 or bandwidth < 0:
        raise ValueError(f"block must be at least 1 and bandwidth at least 0, got block={block}, "
                         f"bandwidth={bandwidth}")
    S = M.shape[0]
    w = bandwidth
    b = max(1, min(block, S))
    n_blocks = -(-S // b)
    Sp = n_blocks * b
    M = jnp.pad(M, ((w, Sp - S), (w, Sp - S)))
    out = jnp.pad(out, (w, Sp - S))

    def eliminate_block(j, carry):
        M, out, scale = carry
        k0 = Sp - (j + 1) * b  # the block's first position; the window [k0 - w, k0 + b) starts at k0 in padded M
        X = jax.lax.dynamic_slice(M, (k0, k0), (w + b, w + b))
        o = jax.lax.dynamic_slice(out, (k0,), (w + b,))
        rows = jnp.concatenate([X[w:, :w], o[w:, None]], axis=1)  # the absorbing set is one more column of F
        A, rows, cols, s_b = _block_steps(X[w:, w:], rows, X[:w, w:])
        upd = _dot(cols, rows)
        X = jnp.concatenate(
            [jnp.concatenate([X[:w, :w] + upd[:, :w], cols], axis=1), jnp.concatenate([rows[:, :w], A], axis=1)]
        )
        o = jnp.concatenate([o[:w] + upd[:, w], rows[:, w]])
        M = jax.lax.dynamic_update_slice(M, X, (k0, k0))
        return M, jax.lax.dynamic_update_slice(out, o, (k0,)), jax.lax.dynamic_update_slice(scale, s_b, (k0,))

    init = (M, out, jnp.zeros((Sp,), M.dtype))
    M, _, scale = jax.lax.fori_loop(0, n_blocks, eliminate_block, init)
    return M[w:w + S, w:w + S], scale[:S]


def bandwidth(M: jax.Array) -> jax.Array:
    """The largest ``|i - j|`` over the non-zero entries of ``M`` (0 for a diagonal or empty ``M``); traced."""
    pos = jnp.arange(M.shape[0])
    return jnp.max(jnp.where(M != 0, jnp.abs(pos[:, None] - pos[None, :]), 0))


class BandOrder(NamedTuple):
    """A state order that keeps an MDP's chains banded (:func:`band_order`): ``order[i]`` is the state at position
    ``i`` (``[S]``, or ``[M, S]`` for a stack of ``M`` MDPs), and ``bandwidth`` bounds ``|pos(s) - pos(s')|`` over
    every transition of positive probability (the largest over a stack's members)."""

    order: np.ndarray
    bandwidth: int


def band_order(mdp: MDP) -> BandOrder:
    """The reverse Cuthill-McKee order (scipy.sparse.csgraph) of an MDP's successor graph, host side (or the
    states' own order where that is no wider).

    The graph joins ``s`` and ``s'`` when some action moves ``s`` to ``s'`` with positive probability (the successor
    lists), in either direction; every policy's chain is a subgraph, so in this order its transition matrix has
    half-bandwidth at most ``bandwidth``, whatever the policy. A stacked MDP gets one order per member (its padding
    states have no transitions to others). The gains of :func:`~jaxmdp.dynamic_programming.gain_vector` then cost
    ``O(S w^2)`` instead of ``O(S^3)`` (``w`` the bandwidth)."""
    succ, succ_p = np.asarray(mdp.succ), np.asarray(mdp.succ_p)
    if succ.ndim == 4:
        members = [_rcm(s, p) for s, p in zip(succ, succ_p)]
        return BandOrder(np.stack([o for o, _ in members]), max(w for _, w in members))
    return BandOrder(*_rcm(succ, succ_p))


def _rcm(succ: np.ndarray, succ_p: np.ndarray) -> tuple[np.ndarray, int]:
    """The reverse Cuthill-McKee order of one MDP's successor graph, or the natural order where its band is no
    wider (RCM is a heuristic: a river of 20 states comes out at 2, against 1 in its own order)."""
    S = succ.shape[0]
    src = np.broadcast_to(np.arange(S)[:, None, None], succ.shape)
    edge = succ_p > 0
    graph = scipy.sparse.coo_matrix((np.ones(int(edge.sum())), (src[edge], succ[edge])), shape=(S, S)).tocsr()
    graph = ((graph + graph.T) > 0).astype(np.int8)

    def width(order: np.ndarray) -> int:
        pos = np.empty(S, np.int64)
        pos[order] = np.arange(S)
        return int(np.max(np.abs(pos[src[edge]] - pos[succ[edge]]), initial=0))

    natural = np.arange(S, dtype=np.int32)
    rcm = np.asarray(reverse_cuthill_mckee(graph.tocsr(), symmetric_mode=True), np.int32)
    w_natural, w_rcm = width(natural), width(rcm)
    return (natural, w_natural) if w_natural <= w_rcm else (rcm, w_rcm)
