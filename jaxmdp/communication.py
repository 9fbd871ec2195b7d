"""Communication classes of MDPs (paper §2.1), by the reference's operational algorithm (docs/families.md §1.9).

1. *Ergodic test.* Start from the strongly connected components (SCCs) of the graph with an edge ``s -> s'``
   (``s != s'``) when **every** action has ``T[s, a, s'] > 0``. Repeatedly link group ``g -> g'`` when some state of
   ``g`` sends positive mass into ``g'`` under every action, and merge the SCCs of that group graph, until nothing
   merges. One group left: **ERGODIC**.
2. Otherwise, one SCC of the graph with an edge when **some** action has positive probability: **COMMUNICATING**.
3. Otherwise, exactly one closed SCC (no action of any member leaves it): **WEAKLY_COMMUNICATING**.
4. Several closed SCCs: **MULTICHAIN**, i.e. none of the three (the reference crashes here; we return a class).

Like the reference, the classification uses the base kernel ``T`` for episodic MDPs too. It runs on the host
(graph algorithms, ``O(S A K)``); batched MDPs give one class per member. Padded states and actions are ignored.
"""

from __future__ import annotations

import enum

import numpy as np

from jaxmdp.mdp import MDP

__all__ = ["CommunicationClass", "communication_class", "strongly_connected_components"]


class CommunicationClass(enum.IntEnum):
    """Communication class; the first three values are the reference's integer codes."""

    ERGODIC = 0
    COMMUNICATING = 1
    WEAKLY_COMMUNICATING = 2
    MULTICHAIN = 3


def strongly_connected_components(adjacency: np.ndarray) -> np.ndarray:
    """SCC labels (0..n_components-1) of a boolean adjacency matrix, by an iterative Kosaraju algorithm."""
    n = adjacency.shape[0]
    rows, cols = np.nonzero(adjacency)
    out = [[] for _ in range(n)]
    inc = [[] for _ in range(n)]
    for r, c in zip(rows.tolist(), cols.tolist()):
        out[r].append(c)
        inc[c].append(r)
    seen = [False] * n
    order: list[int] = []
    for root in range(n):
        if seen[root]:
            continue
        seen[root] = True
        stack = [(root, 0)]
        while stack:
            v, i = stack[-1]
            if i < len(out[v]):
                stack[-1] = (v, i + 1)
                w = out[v][i]
                if not seen[w]:
                    seen[w] = True
                    stack.append((w, 0))
            else:
                stack.pop()
                order.append(v)
    label = [-1] * n
    current = 0
    for root in reversed(order):
        if label[root] != -1:
            continue
        label[root] = current
        todo = [root]
        while todo:
            v = todo.pop()
            for w in inc[v]:
                if label[w] == -1:
                    label[w] = current
                    todo.append(w)
        current += 1
    return np.asarray(label, dtype=np.int64)


def _classify(T: np.ndarray) -> CommunicationClass:
    S = T.shape[0]
    pos = T > 0
    off_diag = ~np.eye(S, dtype=bool)

    src_s, src_a, dst_t = np.nonzero(pos)  # sparse form: these MDPs have a handful of successors per (s, a)
    groups = strongly_connected_components(pos.all(axis=1) & off_diag)
    while True:
        n_groups = int(groups.max()) + 1
        if n_groups == 1:
            return CommunicationClass.ERGODIC
        reaches = np.zeros((S, T.shape[1], n_groups), dtype=bool)  # (s, a) puts mass into group g
        reaches[src_s, src_a, groups[dst_t]] = True
        every_action = reaches.all(axis=1)  # [S, G]
        group_graph = np.zeros((n_groups, n_groups), dtype=bool)
        np.logical_or.at(group_graph, groups, every_action)
        np.fill_diagonal(group_graph, False)
        merged = strongly_connected_components(group_graph)
        if int(merged.max()) + 1 == n_groups:
            break
        groups = merged[groups]

    some = pos.any(axis=1) & off_diag
    scc = strongly_connected_components(some)
    n_scc = int(scc.max()) + 1
    if n_scc == 1:
        return CommunicationClass.COMMUNICATING
    leaves = np.zeros(n_scc, dtype=bool)
    src, dst = np.nonzero(some)
    leaves[scc[src][scc[src] != scc[dst]]] = True
    n_closed = int(np.sum(~leaves))
    return CommunicationClass.WEAKLY_COMMUNICATING if n_closed == 1 else CommunicationClass.MULTICHAIN


def communication_class(mdp: MDP) -> CommunicationClass | list[CommunicationClass]:
    """Communication class of an MDP (a list of classes for a stacked batch); see the module docstring."""
    T = np.asarray(mdp.T)
    smask = np.asarray(mdp.state_mask)
    amask = np.asarray(mdp.action_mask)
    if T.ndim in (3, 4) and (T.shape[-1] != T.shape[-3] or smask.shape != T.shape[:-2] or
                             amask.shape != T.shape[:-3] + T.shape[-2:-1]):
        raise ValueError(
            f"T must be [S, A, S] (or [B, S, A, S]) with state_mask [S] and action_mask [A]; got T {T.shape}, "
            f"state_mask {smask.shape}, action_mask {amask.shape}"
        )
    if T.ndim == 4:
        return [_classify(T[i][smask[i]][:, amask[i]][:, :, smask[i]]) for i in range(T.shape[0])]
    if T.ndim != 3:
        raise ValueError(f"expected an MDP or a batch with one leading axis; T has shape {T.shape}")
    return _classify(T[smask][:, amask][:, :, smask])
