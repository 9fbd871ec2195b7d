"""Batches of MDPs: padding to common shapes (:func:`stack`), the inverse (:func:`unstack`) and state relabelling.

Padding rules (so that one compiled program serves a grid and no trajectory can enter the padding):

* padded **states** are absorbing (every action loops with probability one), pay zero, have ``P0 = 0`` and receive no
  transition from a real state; ``state_mask`` is False there;
* padded **actions** of a real state are copies of action 0 (same transitions and rewards), so maxima and minima over
  actions are unchanged; ``action_mask`` is False there and every average or sum over actions (random policy, gap
  sums, ``p_rand``) uses the mask;
* successor lists are padded with zero-probability self entries;
* time: the static ``H`` becomes the largest horizon and each member keeps its own traced ``horizon``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp.mdp import MDP, MDPInfo

__all__ = ["stack", "unstack", "pad", "permute_states", "state_permutation"]


def pad(mdp: MDP, n_states: int, n_actions: int, n_successors: int, H: int | None = None) -> MDP:
    """Pad one (unbatched) MDP to ``n_states``, ``n_actions``, ``n_successors`` and time length ``H``."""
    S, A, K = mdp.succ.shape
    if mdp.T.ndim != 3:
        raise ValueError("pad expects a single MDP, not a batch")
    if n_states < S or n_actions < A or n_successors < K:
        raise ValueError(f"cannot pad (S, A, K) = {(S, A, K)} down to {(n_states, n_actions, n_successors)}")
    if mdp.episodic and (H is None or H < mdp.H):
        raise ValueError(f"H must be at least the MDP's horizon {mdp.H}; got {H}")
    dS, dA, dK = n_states - S, n_actions - A, n_successors - K
    dt = mdp.dtype

    def pad_actions(x: jax.Array, axis: int) -> jax.Array:
        # Copies of action 0 on the action axis.
        first = jax.lax.index_in_dim(x, 0, axis=axis, keepdims=True)
        return jnp.concatenate([x] + [first] * dA, axis=axis) if dA else x

    T = pad_actions(mdp.T, 1)
    T = jnp.pad(T, ((0, dS), (0, 0), (0, dS)))
    pad_rows = jnp.eye(n_states, dtype=dt)[S:]  # [dS, n_states]
    T = T.at[S:].set(jnp.broadcast_to(pad_rows[:, None, :], (dS, n_actions, n_states)))
    R = jnp.pad(pad_actions(mdp.R, 1), ((0, dS), (0, 0)))
    rm = jnp.pad(pad_actions(mdp.reward_mean, 1), ((0, dS), (0, 0), (0, dS)))
    rc = jnp.pad(pad_actions(mdp.reward_conc, 1), ((0, dS), (0, 0), (0, dS)))

    own = jnp.arange(n_states, dtype=mdp.succ.dtype)
    succ = pad_actions(mdp.succ, 1)
    succ = jnp.concatenate([succ, jnp.broadcast_to(own[:S, None, None], (S, n_actions, dK))], axis=-1)
    succ = jnp.concatenate([succ, jnp.broadcast_to(own[S:, None, None], (dS, n_actions, n_successors))], axis=0)
    succ_p = jnp.pad(pad_actions(mdp.succ_p, 1), ((0, 0), (0, 0), (0, dK)))
    pad_p = jnp.zeros((dS, n_actions, n_successors), dt).at[:, :, 0].set(1.0)
    succ_p = jnp.concatenate([succ_p, pad_p], axis=0)

    return MDP(
        T=T,
        R=R,
        P0=jnp.pad(mdp.P0, (0, dS)),
        reward_mean=rm,
        reward_conc=rc,
        succ=succ,
        succ_p=succ_p,
        state_mask=jnp.pad(mdp.state_mask, (0, dS)),
        action_mask=jnp.pad(mdp.action_mask, (0, dA)),
        horizon=mdp.horizon,
        H=H if mdp.episodic else None,
        info=mdp.info,
        stochastic_rewards=mdp.stochastic_rewards,
    )


def stack(mdps: Sequence[MDP]) -> MDP:
    """Pad MDPs to common ``S``, ``A``, ``K`` (and ``H``) and stack them along a new leading batch axis.

    All members must be episodic or all continuous, with the same dtype. The result's ``info.members`` holds the
    members' metadata; ``jax.vmap`` over the result runs them in lockstep.
    """
    mdps = list(mdps)
    if not mdps:
        raise ValueError("mdps must contain at least one MDP")
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
    padded = [pad(m.strip(), S, A, K, H) for m in mdps]
    stochastic = any(m.stochastic_rewards for m in mdps)
    batch = jax.tree.map(lambda *xs: jnp.stack(xs), *[m.replace(stochastic_rewards=stochastic) for m in padded])
    return batch.replace(info=MDPInfo(family="stack", members=tuple(m.info for m in mdps)))


def unstack(batch: MDP) -> list[MDP]:
    """Split a stacked batch back into its members, removing the padding (inverse of :func:`stack`)."""
    if batch.T.ndim != 4:
        raise ValueError("unstack expects a batch with one leading axis")
    out = []
    n = batch.T.shape[0]
    members = batch.info.members or (MDPInfo(),) * n
    for i in range(n):
        m = jax.tree.map(lambda x: x[i], batch)
        S = int(np.sum(np.asarray(m.state_mask)))
        A = int(np.sum(np.asarray(m.action_mask)))
        keep_k = np.asarray(m.succ_p[:S, :A] > 0).any(axis=(0, 1))
        K = int(np.max(np.nonzero(keep_k)[0]) + 1) if keep_k.any() else 1
        H = int(m.horizon) if batch.H is not None else None
        out.append(
            MDP(
                T=m.T[:S, :A, :S],
                R=m.R[:S, :A],
                P0=m.P0[:S],
                reward_mean=m.reward_mean[:S, :A, :S],
                reward_conc=m.reward_conc[:S, :A, :S],
                succ=m.succ[:S, :A, :K],
                succ_p=m.succ_p[:S, :A, :K],
                state_mask=m.state_mask[:S],
                action_mask=m.action_mask[:A],
                horizon=m.horizon,
                H=H,
                info=members[i],
                stochastic_rewards=bool(np.any(np.asarray(m.reward_conc[:S, :A, :S])[np.asarray(m.T[:S, :A, :S]) > 0] > 0)),
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
    return mdp.replace(
        T=mdp.T[perm][:, :, perm],
        R=mdp.R[perm],
        P0=mdp.P0[perm],
        reward_mean=mdp.reward_mean[perm][:, :, perm],
        reward_conc=mdp.reward_conc[perm][:, :, perm],
        succ=jnp.asarray(inv, mdp.succ.dtype)[mdp.succ[perm]],
        succ_p=mdp.succ_p[perm],
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
