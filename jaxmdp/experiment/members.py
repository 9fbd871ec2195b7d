"""The members of a lockstep run: a flat batch of (MDP, hyperparameters, key) triples.

:func:`product` forms the usual grid, MDPs x hyperparameter sets x seeds; :func:`grid` takes explicit members.
Distinct MDPs are stored once, as one stacked batch (:func:`jaxmdp.stack`), and members refer to them by index, so
memory grows with the number of distinct MDPs, not with the number of members.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp.batching import stack
from jaxmdp.blockmdp.block_mdp import BlockMDP
from jaxmdp.mdp import MDP

__all__ = ["Grid", "grid", "product", "seed_keys", "stack_hparams", "dynamics", "n_distinct", "member_mdp",
           "take_members"]


def take_members(tree: Any, index: np.ndarray | slice) -> Any:
    """Members ``index`` (indices, repeats allowed, or a slice) of every per-member leaf of ``tree``, as numpy: the
    leaves with a leading member axis; a scalar leaf (shared by all members, as the loop's step counter) is kept."""
    return jax.tree.map(lambda x: np.asarray(x) if np.ndim(x) == 0 else np.asarray(x)[index], tree)


@dataclasses.dataclass(frozen=True)
class Grid:
    """A flat batch of ``B`` members.

    Attributes:
      mdps: the distinct MDPs as one stacked batch ``[M]`` (metadata stripped); member ``i`` faces
        ``mdps[mdp_index[i]]``. Keeping distinct MDPs once (instead of one padded copy per member) keeps memory
        proportional to ``M``, not ``B``.
      mdp_index: ``[B]`` index of each member's MDP.
      hparams: the members' hyperparameters, one stacked pytree with leading axis ``B``.
      key_data: ``[B, 2]`` raw threefry key data of each member (``jax.random.key_data`` of its key).
      hparams_index: ``[B]`` label of each member's hyperparameter set (for the output).
      seeds: ``[B]`` label of each member's seed (for the output; ``-1`` when keys were given directly).
      mdp_labels: one label per distinct MDP (for the output).
    """

    mdps: MDP
    mdp_index: np.ndarray
    hparams: Any
    key_data: np.ndarray
    hparams_index: np.ndarray
    seeds: np.ndarray
    mdp_labels: tuple[str, ...]

    @property
    def n_members(self) -> int:
        return int(self.mdp_index.shape[0])

    def take(self, members: Sequence[int] | np.ndarray) -> Grid:
        """The grid of members ``members`` of this one, in that order (repeats allowed); the MDPs are shared."""
        index = np.asarray(members)
        if index.ndim != 1 or not np.issubdtype(index.dtype, np.integer) or not np.all(
                (index >= 0) & (index < self.n_members)):
            raise ValueError(f"members must be a 1-D sequence of member indices in [0, {self.n_members}); got "
                             f"{members!r}")
        return dataclasses.replace(
            self, mdp_index=self.mdp_index[index], hparams=take_members(self.hparams, index),
            key_data=self.key_data[index], hparams_index=self.hparams_index[index], seeds=self.seeds[index],
        )

    @property
    def episodic(self) -> bool:
        return self.mdps.episodic


def _as_stacked(mdps: MDP | Sequence[MDP]) -> tuple[MDP, tuple[str, ...]]:
    stacked, labels = _stack_with_labels(mdps)
    if len(set(labels)) < len(labels):  # e.g. several custom MDPs: number them so the output stays unambiguous
        labels = tuple(f"{label}#{i}" for i, label in enumerate(labels))
    return stacked, labels


def _stack_with_labels(mdps: MDP | BlockMDP | Sequence[MDP | BlockMDP]) -> tuple[MDP, tuple[str, ...]]:
    if isinstance(mdps, (MDP, BlockMDP)):
        T = dynamics(mdps).T
        if T.ndim == 3:
            mdps = [mdps]
        elif T.ndim == 4:
            labels = tuple(_label(m) for m in mdps.info.members) or tuple(f"mdp{i}" for i in range(T.shape[0]))
            return mdps.strip(), labels
        else:
            raise ValueError(f"mdps must be an MDP, a stacked batch of MDPs or a sequence of MDPs; T has shape "
                             f"{T.shape}")
    mdps = list(mdps)
    if not mdps or not (all(isinstance(m, MDP) for m in mdps) or all(isinstance(m, BlockMDP) for m in mdps)):
        raise ValueError("mdps must be a non-empty sequence of MDPs, or of BlockMDPs (jaxmdp.block_mdp)")
    return stack(mdps).strip(), tuple(_label(m.info) for m in mdps)


def dynamics(mdps: MDP | BlockMDP) -> MDP:
    """The MDP whose dynamics the members face: ``mdps`` itself, or the MDP under a BlockMDP's emissions."""
    return mdps.mdp if isinstance(mdps, BlockMDP) else mdps


def n_distinct(mdps: MDP | BlockMDP) -> int:
    """The number ``M`` of stacked MDPs (the leading axis of a :class:`Grid`'s ``mdps``)."""
    return dynamics(mdps).T.shape[0]


def member_mdp(mdps: MDP | BlockMDP, i: jax.Array) -> MDP | BlockMDP:
    """MDP ``i`` of a stack (traceable; ``i`` may be batched under ``vmap``). A stack of one MDP gives it unbatched,
    whatever ``i``, so that a grid of a single MDP gathers nothing."""
    if n_distinct(mdps) == 1:
        return jax.tree.map(lambda x: x[0], mdps)
    return jax.tree.map(lambda x: x[i], mdps)


def _label(info: Any) -> str:
    info = getattr(info, "info", info)
    params = ",".join(f"{k}={v}" for k, v in info.params if not str(k).endswith("distribution"))
    return f"{info.family}({params})" if params else info.family


def stack_hparams(hparams_list: Sequence[Any]) -> Any:
    """Hyperparameter sets stacked along a new leading axis (numpy leaves); static fields must agree."""
    try:
        return jax.tree.map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *hparams_list)
    except ValueError as err:
        raise ValueError(f"all hyperparameter sets must have the same structure and static fields: {err}") from None


def _key_data(keys: Any, n: int) -> np.ndarray:
    keys = jnp.asarray(keys) if not isinstance(keys, jax.Array) else keys
    if jax.dtypes.issubdtype(keys.dtype, jax.dtypes.prng_key):
        if jax.random.key_impl(keys) != jax.random.key_impl(jax.random.key(0)):
            raise ValueError("keys must use the default threefry2x32 implementation")
        keys = jax.random.key_data(keys)
    data = np.asarray(keys)
    if data.shape != (n, 2) or data.dtype != np.uint32:
        raise ValueError(f"keys must be {n} typed keys or uint32 key data of shape ({n}, 2); got {data.shape} "
                         f"{data.dtype}")
    return data


def grid(
    mdps: MDP | Sequence[MDP],
    hparams: Any,
    keys: Any,
    *,
    mdp_index: Sequence[int] | None = None,
    hparams_index: Sequence[int] | None = None,
    seeds: Sequence[int] | None = None,
) -> Grid:
    """A grid from explicit members.

    Args:
      mdps: one MDP, a stacked batch (:func:`jaxmdp.stack`) or a sequence of MDPs: the distinct MDPs.
      hparams: the members' hyperparameters stacked along a leading axis ``B`` (one set per member).
      keys: ``B`` keys (typed keys of ``jax.random.key`` or raw ``uint32[B, 2]`` data).
      mdp_index: member ``i`` faces MDP ``mdp_index[i]`` (default: ``arange(B)`` if there are ``B`` MDPs, or all
        zeros for a single MDP).
      hparams_index, seeds: labels written to the output (default ``arange(B)`` and ``-1``).
    """
    stacked, labels = _as_stacked(mdps)
    M = n_distinct(stacked)
    leaves = jax.tree.leaves(hparams)
    sizes = {np.shape(x)[0] if np.ndim(x) else None for x in leaves}
    if None in sizes or len(sizes) > 1:
        raise ValueError("hparams must be a stacked pytree: every leaf with the same leading (member) axis")
    keys_arr = keys if isinstance(keys, jax.Array) else np.asarray(keys)
    B = sizes.pop() if sizes else int(np.shape(keys_arr)[0])
    if mdp_index is None:
        if M not in (1, B):
            raise ValueError(f"mdp_index is needed to assign {M} MDPs to {B} members")
        mdp_index = np.zeros(B, np.int32) if M == 1 else np.arange(B, dtype=np.int32)
    mdp_index = np.asarray(mdp_index, np.int32)
    if mdp_index.shape != (B,) or mdp_index.min() < 0 or mdp_index.max() >= M:
        raise ValueError(f"mdp_index must be {B} integers in [0, {M}); got shape {mdp_index.shape}")
    hp_index = np.arange(B) if hparams_index is None else np.asarray(hparams_index)
    seeds_arr = np.full(B, -1) if seeds is None else np.asarray(seeds)
    if hp_index.shape != (B,) or seeds_arr.shape != (B,):
        raise ValueError(f"hparams_index and seeds must have shape ({B},)")
    return Grid(
        mdps=stacked,
        mdp_index=mdp_index,
        hparams=jax.tree.map(np.asarray, hparams),
        key_data=_key_data(keys_arr, B),
        hparams_index=hp_index.astype(np.int64),
        seeds=seeds_arr.astype(np.int64),
        mdp_labels=labels,
    )


def seed_keys(seeds: Sequence[int] | np.ndarray) -> jax.Array:
    """``jax.random.key(s)`` for every seed ``s``: the key :func:`product` gives a member of seed ``s``."""
    return jax.vmap(jax.random.key)(jnp.asarray(seeds))


def product(
    mdps: MDP | Sequence[MDP],
    hparams: Sequence[Any],
    seeds: Sequence[int],
) -> Grid:
    """The full product MDPs x hyperparameter sets x seeds, MDP-major then hyperparameters then seed.

    Member ``(m, p, n)`` faces MDP ``m`` with hyperparameter set ``p`` and key ``jax.random.key(seeds[n])``: as in the
    reference, the seed alone defines the agent's randomness, so members that differ only by MDP or
    hyperparameters share their random numbers (common random numbers make comparisons sharper).
    """
    stacked, labels = _as_stacked(mdps)
    M = n_distinct(stacked)
    hparams = list(hparams)
    seeds = [int(s) for s in seeds]
    if not hparams:
        raise ValueError("hparams must hold at least one hyperparameter set")
    if not seeds or any(s < 0 for s in seeds):
        raise ValueError(f"seeds must be a non-empty list of non-negative integers; got {seeds}")
    idx = np.asarray(list(itertools.product(range(M), range(len(hparams)), range(len(seeds)))), np.int64)
    hp_all = stack_hparams(hparams)
    member_hparams = jax.tree.map(lambda x: x[idx[:, 1]], hp_all)
    seed_arr = np.asarray(seeds)[idx[:, 2]]
    key_data = np.asarray(jax.random.key_data(seed_keys(seed_arr)))
    return Grid(
        mdps=stacked,
        mdp_index=idx[:, 0].astype(np.int32),
        hparams=member_hparams,
        key_data=key_data,
        hparams_index=idx[:, 1],
        seeds=seed_arr.astype(np.int64),
        mdp_labels=labels,
    )
