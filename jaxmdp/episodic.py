"""The episodic MDP as a time-augmented object: reachable ``(h, s)`` pairs, ``T_epi`` and the continuous form.

An episodic MDP with horizon ``H`` (paper §2.1) acts at in-episode times ``h = 0 .. H-1`` and is reset to ``P0`` after
the action at ``h = H-1``. Seen as a continuous MDP on *pairs* ``(h, s)`` (the paper's time augmentation, §2.2):
``(h, s) -a-> (h+1, s') ~ P(.|s, a)`` for ``h < H-1`` and ``(H-1, s) -a-> (0, s0) ~ P0``, with reward ``R(s, a)`` at
every pair.

* :func:`reachable_pairs` (jittable): ``Reach_0 = supp P0``, ``Reach_{h+1} = successors(Reach_h)`` (docs/families.md
  §1.8); only these pairs are states of the time-augmented MDP.
* :func:`time_augmented_kernel` (jittable, dense ``[H, S, A, S]``): the reference's ``T_epi``, used by its episodic
  diameter: rows of reachable pairs copy ``T`` for ``h < H-1``, unreachable rows are zero (not stochastic), and row
  ``H-1`` of *every* state jumps to ``P0``.
* :func:`episodic_graph_order` / :func:`continuous_form` (host side): the reference's episodic graph, its depth-first
  node order and its continuous form ``T_cf`` / ``R_cf`` in successor-list layout, including the reset-column quirk
  (docs/families.md §1.8: the reset mass towards start ``s0`` lands on the pair whose *graph index* equals the original
  index of ``s0``). Only the reference's episodic value norm needs them.

Stacked batches: the static ``H`` is the longest horizon and each member's traced ``horizon`` is its own; rows with
``h >= horizon`` are unreachable and the reset happens at ``h = horizon - 1``.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp import struct
from jaxmdp.dynamic_programming import compiled
from jaxmdp.mdp import MDP

__all__ = [
    "reachable_pairs",
    "time_augmented_kernel",
    "graph_successors",
    "start_order",
    "episodic_graph_order",
    "ContinuousForm",
    "continuous_form",
    "stack_continuous_forms",
]


def _require_episodic(mdp: MDP) -> int:
    if mdp.H is None:
        raise ValueError("mdp must be episodic (H is None for a continuous MDP)")
    return mdp.H


@compiled()
def reachable_pairs(mdp: MDP) -> jax.Array:
    """Boolean ``[H, S]`` mask of the pairs ``(h, s)`` reachable within an episode (docs/families.md §1.8).

    ``Reach_0 = supp(P0)`` (valid states only) and ``Reach_{h+1} = {s' : P(s'|s,a) > 0, s in Reach_h, a valid}`` for
    ``h + 1 < horizon``; rows ``h >= horizon`` are False. Jitted (:func:`jaxmdp.dynamic_programming.compiled`); vmaps
    over a stacked batch.
    """
    H = _require_episodic(mdp)
    S = mdp.n_states
    reach0 = (mdp.P0 > 0) & mdp.state_mask
    edge = (mdp.succ_p > 0) & mdp.action_mask[None, :, None]

    def step(reach, h):
        arriving = (reach[:, None, None] & edge).astype(jnp.int32)
        nxt = jnp.zeros((S,), jnp.int32).at[mdp.succ.ravel()].max(arriving.ravel()) > 0
        nxt = nxt & (h < mdp.horizon)
        return nxt, nxt

    _, rest = jax.lax.scan(step, reach0, jnp.arange(1, H))
    return jnp.concatenate([reach0[None], rest], axis=0)


def time_augmented_kernel(mdp: MDP) -> jax.Array:
    """The reference's ``T_epi[H, S, A, S]`` (docs/families.md §1.8), dense.

    ``T_epi[h, s] = T[s]`` if ``(h, s)`` is reachable and ``h < horizon - 1``, zero otherwise;
    ``T_epi[horizon - 1, s, a] = P0`` for every state and action. Memory ``H S^2 A``: meant for small MDPs and tests;
    the measures use the successor lists and :func:`reachable_pairs` instead.
    """
    H = _require_episodic(mdp)
    reach = reachable_pairs(mdp)
    h = jnp.arange(H)[:, None, None, None]
    body = jnp.where(reach[:, :, None, None] & (h < mdp.horizon - 1), mdp.T[None], 0.0)
    reset = jnp.broadcast_to(mdp.P0, mdp.T.shape)[None]
    return jnp.where(h == mdp.horizon - 1, reset, body)


# ---------------------------------------------------------------------------------------------------------------
# Host side: the reference's episodic graph and continuous form
# ---------------------------------------------------------------------------------------------------------------


def graph_successors(mdp: MDP) -> list[list[int]]:
    """Graph successors of every valid state, in the order the reference created their edges (host side).

    The reference iterates a node's successors in edge-creation order: the effective outcome lists of base actions
    ``0, 1, ...`` in list order (docs/families.md §1.6). When the family recorded that order in
    ``mdp.info.layout["successor_order"]`` it is used; otherwise the order is rebuilt from the successor lists
    (action by action, increasing state index), which coincides with the reference for RiverSwim and DeepSea but may
    differ for other families. The order only matters for :func:`episodic_graph_order`.
    """
    S = int(np.sum(np.asarray(mdp.state_mask)))
    succ, succ_p = np.asarray(mdp.succ), np.asarray(mdp.succ_p)
    A = int(np.sum(np.asarray(mdp.action_mask)))
    out = []
    for s in range(S):
        seen: dict[int, None] = {}
        for a in range(A):
            for t, p in zip(succ[s, a], succ_p[s, a]):
                if p > 0:
                    seen.setdefault(int(t), None)
        out.append(list(seen))
    recorded = mdp.info.layout_value("successor_order")
    # A recorded order is used only if it still describes this kernel (a relabelled MDP keeps stale metadata).
    if recorded is not None and len(recorded) == S and all(set(r) == set(o) for r, o in zip(recorded, out)):
        return [list(r) for r in recorded]
    return out


def start_order(mdp: MDP) -> list[int]:
    """Starting states in the order the reference lists them (host side).

    That is the family's starting-node sampler order, recorded by the family in
    ``mdp.info.layout["start_order"]``; without it, increasing index (the first start always has index 0).
    """
    recorded = mdp.info.layout_value("start_order")
    if recorded is not None:
        return [int(s) for s in recorded]
    return [int(s) for s in np.nonzero(np.asarray(mdp.P0) > 0)[0]]


def _concrete_horizon(mdp: MDP) -> int:
    _require_episodic(mdp)
    try:
        return int(mdp.horizon)
    except (jax.errors.ConcretizationTypeError, TypeError):
        raise ValueError("episodic_graph_order / continuous_form run on the host: call them outside jit") from None


def episodic_graph_order(
    mdp: MDP, successors: Sequence[Sequence[int]] | None = None, starts: Sequence[int] | None = None
) -> np.ndarray:
    """The reachable pairs ``(h, s)`` in the reference's episodic-graph insertion order, an ``[N, 2]`` int array.

    Depth-first from ``(0, s0)`` for every start ``s0`` (in ``starts`` order, default :func:`start_order`): from ``(h, s)`` the children are
    ``(h+1, s')`` for the graph successors ``s'`` of ``s`` (:func:`graph_successors` order) when ``h < H-1`` and the
    start pairs ``(0, s0)`` when ``h = H-1``; a newly reached child is appended and, when the parent has
    ``h < H-1``, expanded immediately. Host side (the order is inherently sequential).
    """
    H = _concrete_horizon(mdp)
    succ = graph_successors(mdp) if successors is None else [list(x) for x in successors]
    starts = start_order(mdp) if starts is None else [int(s) for s in starts]
    order: list[tuple[int, int]] = []
    seen: set[tuple[int, int]] = set()

    def children(h: int, s: int) -> Iterator[tuple[int, int]]:
        return iter([(h + 1, t) for t in succ[s]] if h < H - 1 else [(0, s0) for s0 in starts])

    for s0 in starts:
        if (0, s0) not in seen:
            seen.add((0, s0))
            order.append((0, s0))
        # Depth-first with an explicit stack of (pair, its remaining children): a path is up to H pairs long, too
        # deep for Python's recursion limit on long horizons.
        stack = [((0, s0), children(0, s0))]
        while stack:
            (h, _), pending = stack[-1]
            for c in pending:
                if c not in seen:
                    seen.add(c)
                    order.append(c)
                    if h < H - 1:  # expand the new child before the parent's next one
                        stack.append((c, children(*c)))
                        break
            else:
                stack.pop()
    return np.asarray(order, dtype=np.int32).reshape(-1, 2)


class ContinuousForm(struct.PyTreeNode):
    """An episodic MDP as a continuous MDP on its reachable pairs, in successor-list layout.

    Row ``i`` is the pair ``(pair_h[i], pair_s[i])``. ``succ[i, a, k]`` / ``succ_p[i, a, k]`` are row indices and
    probabilities, ``R[i, a] = R(s, a)``; ``row_mask`` marks real rows (False for padding added by
    :func:`stack_continuous_forms`); ``action_mask`` is the MDP's.
    """

    succ: jax.Array
    succ_p: jax.Array
    R: jax.Array
    pair_h: jax.Array
    pair_s: jax.Array
    row_mask: jax.Array
    action_mask: jax.Array

    @property
    def n_rows(self) -> int:
        return self.succ.shape[-3]


def continuous_form(mdp: MDP, order: np.ndarray | None = None, *, reset_quirk: bool = True) -> ContinuousForm:
    """The reference's continuous form ``T_cf`` / ``R_cf`` of an episodic MDP (docs/families.md §1.8), host side.

    Rows follow ``order`` (default :func:`episodic_graph_order`). For ``h < H-1`` row ``(h, s)`` moves to the rows of
    ``(h+1, s')`` with ``T[s, a, s']``; row ``(H-1, s)`` resets with ``P0``. With ``reset_quirk=True`` (the
    reference) the reset mass of start ``s0`` goes to row number ``s0`` (its original state index) instead of the row
    of ``(0, s0)``; the two coincide when the only start has index 0. ``reset_quirk=False`` gives the faithful
    time-augmented MDP.
    """
    H = _concrete_horizon(mdp)
    order = episodic_graph_order(mdp) if order is None else np.asarray(order, dtype=np.int32)
    succ, succ_p = np.asarray(mdp.succ), np.asarray(mdp.succ_p)
    S, A, K = succ.shape
    P0 = np.asarray(mdp.P0)
    starts = np.nonzero(P0 > 0)[0]
    N = len(order)
    row_of = -np.ones((H, S), dtype=np.int64)
    row_of[order[:, 0], order[:, 1]] = np.arange(N)
    if reset_quirk:
        if starts.max(initial=0) >= N:
            raise ValueError(
                f"the reference's continuous form (variant='colosseum', reset_quirk=True) sends the reset mass of start "
                f"state {int(starts.max())} to row {int(starts.max())}, but this MDP reaches only {N} (h, s) pairs; "
                "the reference cannot represent it: use variant='paper' (or reset_quirk=False)"
            )
        reset_cols = starts
    else:
        reset_cols = row_of[0, starts]
    Kc = max(K, len(starts))
    out_succ = np.zeros((N, A, Kc), dtype=np.int32)
    out_p = np.zeros((N, A, Kc), dtype=np.asarray(mdp.succ_p).dtype)
    h, s = order[:, 0], order[:, 1]
    body = h < H - 1
    nxt = row_of[np.minimum(h[body] + 1, H - 1)[:, None, None], succ[s[body]]]
    pb = succ_p[s[body]]
    if np.any((nxt < 0) & (pb > 0)):
        raise ValueError("order is missing a reachable pair")
    out_succ[body, :, :K] = np.where(pb > 0, nxt, 0)
    out_p[body, :, :K] = pb
    out_succ[~body, :, : len(starts)] = reset_cols
    out_p[~body, :, : len(starts)] = P0[starts]
    R = np.asarray(mdp.R)[s]
    return ContinuousForm(
        succ=jnp.asarray(out_succ),
        succ_p=jnp.asarray(out_p),
        R=jnp.asarray(R),
        pair_h=jnp.asarray(h),
        pair_s=jnp.asarray(s),
        row_mask=jnp.ones((N,), bool),
        action_mask=jnp.asarray(mdp.action_mask),
    )


def stack_continuous_forms(forms: Sequence[ContinuousForm]) -> ContinuousForm:
    """Pad continuous forms to common ``N``, ``A``, ``K`` and stack them (padded rows are absorbing with reward 0,
    padded actions copy action 0, as in :func:`jaxmdp.stack`)."""
    N = max(f.n_rows for f in forms)
    A = max(f.succ.shape[1] for f in forms)
    K = max(f.succ.shape[2] for f in forms)
    out = []
    for f in forms:
        n, a, k = f.succ.shape
        succ = np.zeros((N, A, K), np.int32)
        p = np.zeros((N, A, K), np.asarray(f.succ_p).dtype)
        R = np.zeros((N, A), np.asarray(f.R).dtype)
        fs, fp, fR = np.asarray(f.succ), np.asarray(f.succ_p), np.asarray(f.R)
        succ[:n, :a, :k], p[:n, :a, :k], R[:n, :a] = fs, fp, fR
        succ[:n, a:, :k], p[:n, a:, :k], R[:n, a:] = fs[:, :1], fp[:, :1], fR[:, :1]
        succ[n:] = np.arange(n, N)[:, None, None]
        p[n:, :, 0] = 1.0
        out.append(
            ContinuousForm(
                succ=jnp.asarray(succ),
                succ_p=jnp.asarray(p),
                R=jnp.asarray(R),
                pair_h=jnp.pad(f.pair_h, (0, N - n)),
                pair_s=jnp.pad(f.pair_s, (0, N - n)),
                row_mask=jnp.pad(f.row_mask, (0, N - n)),
                action_mask=jnp.pad(f.action_mask, (0, A - a)),
            )
        )
    return jax.tree.map(lambda *xs: jnp.stack(xs), *out)
