"""Batches of MDPs: padding to common shapes (:func:`stack`), the inverse (:func:`unstack`) and state relabelling.

Padding rules (so that one compiled program serves a grid and no trajectory can enter the padding):

* padded **states** are absorbing (every action loops with probability one), pay zero, have ``P0 = 0`` and receive no
  transition from a real state; ``state_mask`` is False there;
* padded **actions** of a real state are copies of action 0 (same transitions and rewards), so maxima and minima over
  actions are unchanged; ``action_mask`` is False there and every average or sum over actions (random policy, gap
  sums, ``p_rand``) uses the mask;
* successor lists are padded with zero-probability self entries, start lists by repeating the last start
  (:func:`jaxmdp.mdp.start_lists`);
* time: the static ``H`` becomes the largest horizon and each member keeps its own traced ``horizon``.

Padding costs work: every member of a stack pays for the largest one. :func:`size_buckets` splits a heterogeneous
collection into a few stacks of similar sizes, so that a handful of compiled programs serve it with little padding.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp._checks import check_int
from jaxmdp.blockmdp.block_mdp import BlockMDP
from jaxmdp.blockmdp.stacking import check_stackable, stack_blocks, unstack_blocks
from jaxmdp._memory import check_memory
from jaxmdp.mdp import MDP, MDPInfo, mdp_array_bytes, start_lists

__all__ = ["stack", "unstack", "pad", "size_buckets", "permute_states", "state_permutation", "stack_bytes"]

# The traced leaves of an MDP.
_ARRAY_FIELDS = (
    "T",
    "R",
    "P0",
    "reward_mean",
    "reward_conc",
    "succ",
    "succ_p",
    "start",
    "start_cdf",
    "state_mask",
    "action_mask",
    "horizon",
)


def stack_bytes(n: int, S: int, A: int, K: int, itemsize: int, n_starts: int = 1) -> int:
    """Peak bytes of padding ``n`` MDPs to ``S`` states, ``A`` actions, ``K`` successors and ``n_starts`` starts
    and stacking them (``n = 1``: :func:`pad`): every member's padded arrays on the host and the stacked copy on the
    device (:func:`~jaxmdp.mdp.mdp_array_bytes` twice per member), one stacked field on the host at a time (at most
    a dense ``[n, S, A, S]``), and a member's dense array read back and gathered over actions while it is padded."""
    dense = int(S) * int(A) * int(S) * int(itemsize)
    return 2 * int(n) * mdp_array_bytes(S, A, K, itemsize, n_starts) + int(n) * dense + 2 * dense


def _check_stack_memory(what: str, n: int, S: int, A: int, K: int, H: int | None, itemsize: int, n_starts: int) -> None:
    sizes = {"members": n, "S": S, "A": A, "K": K} if what == "stack" else {"S": S, "A": A, "K": K}
    if H is not None:
        sizes["H"] = H
    if what == "stack":
        remedy = "stack fewer or smaller MDPs (jaxmdp.size_buckets splits a collection into stacks of similar sizes)"
    else:
        remedy = "pad to smaller sizes"
    check_memory(
        stack_bytes(n, S, A, K, itemsize, n_starts),
        f"jaxmdp.{what}",
        sizes,
        detail=f"{n} padded member{'s' if n > 1 else ''} of dense [S, A, S] arrays",
        device_bytes=n * mdp_array_bytes(S, A, K, itemsize, n_starts),
        remedy=f"{remedy}, use a narrower dtype (float32 rather than float64), or a machine with more memory",
    )


def _pad_host(
    mdp: MDP, n_states: int, n_actions: int, n_successors: int, H: int | None, n_starts: int
) -> dict[str, np.ndarray]:
    """The padded arrays of one MDP as numpy arrays (host side: padding is pure data movement, and eager ``jnp``
    ops on members of different shapes would compile a fresh XLA program for every op and member)."""
    if mdp.T.ndim != 3:
        raise ValueError("pad expects a single MDP, not a batch")
    S, A, K = mdp.succ.shape
    if n_states < S or n_actions < A or n_successors < K:
        raise ValueError(f"cannot pad (S, A, K) = {(S, A, K)} down to {(n_states, n_actions, n_successors)}")
    if n_starts < mdp.max_starts:
        raise ValueError(f"cannot pad the start list of length {mdp.max_starts} down to {n_starts}")
    if mdp.episodic and (H is None or H < mdp.H):
        raise ValueError(f"H must be at least the MDP's horizon {mdp.H}; got {H}")
    if not mdp.episodic and H is not None:
        raise ValueError(f"H is for episodic MDPs only; got H={H} for a continuous MDP")
    dt = np.dtype(mdp.dtype)
    # Padded actions copy action 0; padded states get the defaults set below.
    acts = np.concatenate([np.arange(A), np.zeros(n_actions - A, np.int64)])

    def dense(x, fill=0.0):
        out = np.full((n_states, n_actions, n_states), fill, dt)
        out[:S, :, :S] = np.asarray(x)[:, acts]
        return out

    T = dense(mdp.T)
    T[np.arange(S, n_states), :, np.arange(S, n_states)] = 1.0  # padded states are absorbing
    R = np.zeros((n_states, n_actions), dt)
    R[:S] = np.asarray(mdp.R)[:, acts]
    own = np.arange(n_states, dtype=np.asarray(mdp.succ).dtype)
    succ = np.broadcast_to(own[:, None, None], (n_states, n_actions, n_successors)).copy()  # zero-probability self
    succ[:S, :, :K] = np.asarray(mdp.succ)[:, acts]
    succ_p = np.zeros((n_states, n_actions, n_successors), dt)
    succ_p[:S, :, :K] = np.asarray(mdp.succ_p)[:, acts]
    succ_p[S:, :, 0] = 1.0

    reward_mean, reward_conc = dense(mdp.reward_mean), dense(mdp.reward_conc)

    def pad_starts(x):
        x = np.asarray(x)
        return np.concatenate([x, np.full(n_starts - x.size, x[-1], x.dtype)])

    return dict(
        T=T,
        R=R,
        P0=np.pad(np.asarray(mdp.P0), (0, n_states - S)),
        reward_mean=reward_mean,
        reward_conc=reward_conc,
        succ=succ,
        succ_p=succ_p,
        start=pad_starts(mdp.start),
        start_cdf=pad_starts(mdp.start_cdf),
        state_mask=np.pad(np.asarray(mdp.state_mask), (0, n_states - S)),
        action_mask=np.pad(np.asarray(mdp.action_mask), (0, n_actions - A)),
        horizon=np.asarray(mdp.horizon),
    )


def pad(
    mdp: MDP, n_states: int, n_actions: int, n_successors: int, H: int | None = None, n_starts: int | None = None
) -> MDP:
    """Pad one (unbatched) MDP to ``n_states``, ``n_actions``, ``n_successors``, time length ``H`` and start-list
    length ``n_starts`` (default: unchanged), host side."""
    n_starts = mdp.max_starts if n_starts is None else n_starts
    if mdp.T.ndim == 3:
        _check_stack_memory(
            "pad", 1, int(n_states), int(n_actions), int(n_successors), H, np.dtype(mdp.dtype).itemsize, int(n_starts)
        )
    arrays = _pad_host(mdp, n_states, n_actions, n_successors, H, n_starts)
    return mdp.replace(H=H if mdp.episodic else None, **{k: jax.device_put(v) for k, v in arrays.items()})


def stack(mdps: Sequence[MDP] | Sequence[BlockMDP]) -> MDP | BlockMDP:
    """Pad MDPs to common ``S``, ``A``, ``K`` (and ``H``) and stack them along a new leading batch axis.

    All members must be episodic or all continuous, with the same dtype. The result's ``info.members`` holds the
    members' metadata; ``jax.vmap`` over the result runs them in lockstep. Host side (numpy), one transfer per field.
    BlockMDPs stack likewise (:mod:`jaxmdp.blockmdp.stacking`: same emission, noise and observation shape).
    """
    mdps = list(mdps)
    if not mdps:
        raise ValueError("mdps must contain at least one MDP")
    if any(isinstance(m, BlockMDP) for m in mdps):
        blocks = check_stackable(mdps)
        return stack_blocks(blocks, stack([b.mdp for b in blocks]))
    if any(m.T.ndim != 3 for m in mdps):
        raise ValueError("stack expects unbatched MDPs")
    if len({m.episodic for m in mdps}) != 1:
        raise ValueError("cannot stack episodic and continuous MDPs together")
    if len({m.dtype for m in mdps}) != 1:
        raise ValueError(f"all MDPs must share a dtype; got {sorted({str(m.dtype) for m in mdps})}")
    S = max(m.n_states for m in mdps)
    A = max(m.n_actions for m in mdps)
    K = max(m.max_successors for m in mdps)
    H = max(m.H for m in mdps) if mdps[0].episodic else None
    K0 = max(m.max_starts for m in mdps)
    _check_stack_memory("stack", len(mdps), S, A, K, H, np.dtype(mdps[0].dtype).itemsize, K0)
    padded = [_pad_host(m, S, A, K, H, K0) for m in mdps]
    # device_put, not jnp.asarray: the latter compiles a small program per shape (JAX 0.10), a cost every stack paid.
    arrays = {k: jax.device_put(np.stack([p[k] for p in padded])) for k in padded[0]}
    return MDP(
        **arrays,
        H=H,
        info=MDPInfo(family="stack", members=tuple(m.info for m in mdps)),
        stochastic_rewards=any(m.stochastic_rewards for m in mdps),
    )


def size_buckets(mdps: Sequence[MDP], n_buckets: int) -> list[list[int]]:
    """Split ``mdps`` (all episodic or all continuous) into at most ``n_buckets`` groups to :func:`stack` separately.

    With the members sorted by ``(S, A, K, H)``, the groups are the contiguous runs that minimise the padded work
    ``sum_b |b| * S_b^2 * A_b * K_b * H_b`` (``X_b`` the largest ``X`` in group ``b``; ``H = 1`` when continuous), the
    cost of one all-pairs backup per member, found by dynamic programming over the ``O(n^2)`` runs. Returns the
    members' indices per group, smallest group first; every index appears once.
    """
    mdps = list(mdps)
    n_buckets = check_int("n_buckets", n_buckets)
    if not mdps:
        return []
    if len({m.episodic for m in mdps}) > 1:
        raise ValueError("size_buckets needs MDPs that are all episodic or all continuous")
    dims = np.array([(m.n_states, m.n_actions, m.max_successors, m.H or 1) for m in mdps], np.float64)
    order = np.lexsort(dims.T[::-1])
    dims = dims[order]
    n = len(mdps)
    # cost[i, j]: members order[i:j] stacked together.
    cost = np.full((n + 1, n + 1), np.inf)
    for i in range(n):
        top = np.maximum.accumulate(dims[i:], axis=0)
        size = np.arange(1, n - i + 1)
        cost[i, i + 1 :] = size * top[:, 0] ** 2 * top[:, 1] * top[:, 2] * top[:, 3]
    best = np.full((int(n_buckets) + 1, n + 1), np.inf)
    cut = np.zeros((int(n_buckets) + 1, n + 1), np.int64)
    best[0, 0] = 0.0
    for b in range(1, int(n_buckets) + 1):
        for j in range(1, n + 1):
            total = best[b - 1, :j] + cost[:j, j]
            cut[b, j] = int(np.argmin(total))
            best[b, j] = total[cut[b, j]]
    b = int(np.argmin(best[:, n]))
    groups, j = [], n
    while j > 0:
        i = cut[b, j]
        groups.append([int(k) for k in order[i:j]])
        j, b = i, b - 1
    return groups[::-1]


def unstack(batch: MDP | BlockMDP) -> list[MDP] | list[BlockMDP]:
    """Split a stacked batch back into its members, removing the padding (inverse of :func:`stack`; host side)."""
    if isinstance(batch, BlockMDP):
        return unstack_blocks(batch, unstack(batch.mdp))
    if batch.T.ndim != 4:
        raise ValueError("unstack expects a batch with one leading axis")
    arrays = {k: np.asarray(getattr(batch, k)) for k in _ARRAY_FIELDS}
    n = batch.T.shape[0]
    members = batch.info.members or (MDPInfo(),) * n
    out = []
    for i in range(n):
        m = {k: v[i] for k, v in arrays.items()}
        S = int(np.sum(m["state_mask"]))
        A = int(np.sum(m["action_mask"]))
        keep_k = (m["succ_p"][:S, :A] > 0).any(axis=(0, 1))
        K = int(np.max(np.nonzero(keep_k)[0]) + 1) if keep_k.any() else 1
        T = m["T"][:S, :A, :S]
        conc = m["reward_conc"][:S, :A, :S]
        K0 = int(np.sum(m["P0"][:S] > 0))
        member = dict(
            T=T,
            R=m["R"][:S, :A],
            P0=m["P0"][:S],
            reward_mean=m["reward_mean"][:S, :A, :S],
            reward_conc=conc,
            succ=m["succ"][:S, :A, :K],
            succ_p=m["succ_p"][:S, :A, :K],
            start=m["start"][:K0],
            start_cdf=m["start_cdf"][:K0],
            state_mask=m["state_mask"][:S],
            action_mask=m["action_mask"][:A],
            horizon=m["horizon"],
        )
        out.append(
            MDP(
                **{k: jax.device_put(v) for k, v in member.items()},
                H=int(m["horizon"]) if batch.H is not None else None,
                info=members[i],
                stochastic_rewards=bool(np.any(conc[T > 0] > 0)),
            )
        )
    return out


def permute_states(mdp: MDP, perm: Sequence[int] | np.ndarray) -> MDP:
    """Relabel states: state ``i`` of the result is state ``perm[i]`` of ``mdp``."""
    perm = np.asarray(perm)
    S = mdp.n_states
    if sorted(perm.tolist()) != list(range(S)):
        raise ValueError(f"perm must be a permutation of range({S})")
    inv = np.argsort(perm)
    info = mdp.info
    if info.node_labels:
        info = _permute_info(info, perm)
    start, start_cdf = start_lists(np.asarray(mdp.P0)[perm], mdp.max_starts)
    return mdp.replace(
        T=mdp.T[perm][:, :, perm],
        R=mdp.R[perm],
        P0=mdp.P0[perm],
        reward_mean=mdp.reward_mean[perm][:, :, perm],
        reward_conc=mdp.reward_conc[perm][:, :, perm],
        succ=jnp.asarray(inv, mdp.succ.dtype)[mdp.succ[perm]],
        succ_p=mdp.succ_p[perm],
        start=jnp.asarray(start),
        start_cdf=jnp.asarray(start_cdf),
        state_mask=mdp.state_mask[perm],
        info=info,
    )


def _permute_info(info: MDPInfo, perm: np.ndarray) -> MDPInfo:
    labels = tuple(info.node_labels[i] for i in perm)
    values = tuple(info.node_values[i] for i in perm) if info.node_values else ()
    return dataclasses.replace(info, node_labels=labels, node_values=values)


def state_permutation(a: MDP, b: MDP) -> np.ndarray:
    """The permutation ``perm`` with ``permute_states(a, perm)`` listing states in ``b``'s order (by node label)."""
    la, lb = a.info.node_labels, b.info.node_labels
    if not la or sorted(la) != sorted(lb):
        raise ValueError("the two MDPs must have the same set of node labels")
    index = {label: i for i, label in enumerate(la)}
    return np.asarray([index[label] for label in lb])
