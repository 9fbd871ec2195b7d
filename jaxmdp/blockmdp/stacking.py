"""Stacking BlockMDPs (the BlockMDP half of :func:`jaxmdp.stack` / :func:`jaxmdp.unstack`).

The MDPs are padded and stacked as :mod:`jaxmdp.batching` does; each emission table is padded with zero rows for the
padded states (and, episodic, for the steps past the member's horizon, which an episode never reaches) and stacked;
the noise parameters are stacked as they are. The members must share the emission kind, the noise kind and the
observation shape, except that noiseless ``one_hot`` members of different sizes are padded to the largest ``S`` (the
one-hot vector of a state gains trailing zeros, which carry no information, marked by ``obs_mask`` as
:func:`~jaxmdp.blockmdp.block_mdp.pad_observations` marks its padding; members of other emissions and shapes stack
after that function has padded them to one shape).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from jaxmdp._memory import check_memory
from jaxmdp.blockmdp.block_mdp import BlockMDP
from jaxmdp.mdp import MDP

__all__ = ["check_stackable", "stack_blocks", "unstack_blocks"]


def _pads_one_hot(blocks: Sequence[BlockMDP]) -> bool:
    return blocks[0].emission_kind == "one_hot" and blocks[0].noise_kind is None


def check_stackable(items: Sequence[object]) -> list[BlockMDP]:
    """``items`` as a list of unbatched BlockMDPs that can be stacked; ``ValueError`` saying why not otherwise."""
    items = list(items)
    if not all(isinstance(b, BlockMDP) for b in items):
        kinds = sorted({type(b).__name__ for b in items})
        raise ValueError(f"cannot stack BlockMDPs with other objects (got {', '.join(kinds)}); wrap every MDP with "
                         "jaxmdp.block_mdp first")
    for what in ("emission_kind", "noise_kind"):
        values = {getattr(b, what) for b in items}
        if len(values) > 1:
            raise ValueError(f"cannot stack BlockMDPs with different {what}s: {sorted(map(str, values))}")
    if any(b.mdp.T.ndim != 3 for b in items):
        raise ValueError("stack expects unbatched BlockMDPs")
    shapes = {b.obs_shape for b in items}
    if len(shapes) > 1 and not _pads_one_hot(items):
        raise ValueError(f"cannot stack BlockMDPs with different observation shapes: {sorted(shapes)}; pad them to "
                         "one shape first (jaxmdp.pad_observations)")
    return items


def stack_blocks(blocks: Sequence[BlockMDP], stacked: MDP) -> BlockMDP:
    """Stack checked ``blocks`` (:func:`check_stackable`) whose MDPs were stacked into ``stacked``."""
    S, H = stacked.n_states, stacked.H
    obs_shape = (S,) if _pads_one_hot(blocks) else blocks[0].obs_shape
    lead = (H, S) if H is not None else (S,)
    entries = len(blocks) * math.prod((*lead, *obs_shape))
    # Each padded table on the host, their stack, and its copy on the device.
    itemsize = np.dtype(blocks[0].emissions.dtype).itemsize
    check_memory(
        3 * entries * itemsize,
        "jaxmdp.stack (the emission tables)",
        {"members": len(blocks), "S": S, "H": H, "obs_shape": obs_shape},
        device_bytes=entries * itemsize,
        remedy="stack fewer or smaller BlockMDPs, or use a machine with more memory",
    )
    tables = []
    for b in blocks:
        table = np.asarray(b.emissions)
        out = np.zeros((*lead, *obs_shape), table.dtype)
        out[tuple(slice(0, n) for n in table.shape)] = table
        tables.append(out)

    def leaf(name: str):
        values = [getattr(b, name) for b in blocks]
        return None if values[0] is None else jnp.asarray(np.stack([np.asarray(v) for v in values]))

    def mask(b: BlockMDP) -> np.ndarray:
        out = np.zeros(obs_shape, stacked.dtype)
        own = np.ones(b.obs_shape, stacked.dtype) if b.obs_mask is None else np.asarray(b.obs_mask)
        out[tuple(slice(0, n) for n in own.shape)] = own
        return out

    padded = any(b.obs_mask is not None or b.obs_shape != obs_shape for b in blocks)

    return BlockMDP(
        mdp=stacked,
        emissions=jnp.asarray(np.stack(tables)),
        noise_scale=leaf("noise_scale"),
        noise_df=leaf("noise_df"),
        noise_chol=leaf("noise_chol"),
        emission_kind=blocks[0].emission_kind,
        noise_kind=blocks[0].noise_kind,
        obs_shape=obs_shape,
        obs_mask=jnp.asarray(np.stack([mask(b) for b in blocks])) if padded else None,
    )


def unstack_blocks(batch: BlockMDP, members: Sequence[MDP]) -> list[BlockMDP]:
    """Split a stacked BlockMDP whose MDP unstacks into ``members`` (inverse of :func:`stack_blocks`)."""
    one_hot = batch.emission_kind == "one_hot"
    out = []
    for i, m in enumerate(members):
        S = m.n_states
        table = batch.emissions[i, : m.H] if m.episodic else batch.emissions[i]
        table = table[:, :S] if m.episodic else table[:S]
        obs_shape = batch.obs_shape
        obs_mask = None if batch.obs_mask is None else batch.obs_mask[i]
        if one_hot and batch.noise_kind is None:
            table, obs_shape = table[..., :S], (S,)
            obs_mask = None if obs_mask is None or bool(np.all(np.asarray(obs_mask)[:S])) else obs_mask[:S]
        out.append(
            BlockMDP(
                mdp=m,
                emissions=table,
                noise_scale=batch.noise_scale[i],
                noise_df=batch.noise_df[i],
                noise_chol=None if batch.noise_chol is None else batch.noise_chol[i],
                emission_kind=batch.emission_kind,
                noise_kind=batch.noise_kind,
                obs_shape=obs_shape,
                obs_mask=obs_mask,
            )
        )
    return out
