"""BlockMDPs: a tabular MDP seen through an emission map and emission noise (paper §3.1 and App. A.2).

A BlockMDP ``(S, A, P, P0, R, O, q)`` emits, instead of the state ``s``, an observation ``o ~ q(. | s)``; here
``o = table[h, s] + e`` (continuous: ``table[s] + e``), the row of the noiseless emission table
(:func:`~jaxmdp.blockmdp.emission_maps.emission_table`) plus one noise draw ``e`` (:mod:`jaxmdp.blockmdp.noise`).
The states, rewards and dynamics are the MDP's, so every hardness measure and regret of the MDP holds for the
BlockMDP unchanged.

:func:`jaxmdp.reset` and :func:`jaxmdp.step` accept a :class:`BlockMDP` wherever they accept an MDP and return
observations instead of state indices; the state trajectory is the MDP's for the same keys (the noise is drawn from
:func:`noise_key` of the key, a stream the MDP's sampler never uses).
"""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp import struct
from jaxmdp.blockmdp.emission_maps import check_emission_kind, emission_table
from jaxmdp.blockmdp.noise import (
    CORRELATED_NOISE_KINDS,
    check_noise_kind,
    noise_parameters,
    sample_noise,
    wishart_cholesky,
)
from jaxmdp.mdp import MDP

__all__ = ["BlockMDP", "block_mdp", "observe", "noise_key", "pad_observations"]

# fold_in constants: the noise stream of a step's key and the Wishart stream of block_mdp's key.
_NOISE_STREAM = 0x6E6F6973
_WISHART_STREAM = 0x77697368


@struct.dataclass
class BlockMDP:
    """An MDP with an emission table and emission noise (a pytree; see the module docstring).

    Attributes:
      mdp: the underlying MDP (possibly a stacked batch).
      emissions: the noiseless emission table, ``[S, *obs_shape]`` or ``[H, S, *obs_shape]`` (batch axes first).
      noise_scale: the noise's ``scale`` (a traced scalar per member; 0 without noise).
      noise_df: the noise's degrees of freedom (0 for the Gaussian kinds and without noise).
      noise_chol: ``[d, d]`` Cholesky factor of the Wishart covariance (shape) matrix of the correlated kinds,
        ``d = prod(obs_shape)``; ``None`` otherwise.
      emission_kind: static, the emission map's name.
      noise_kind: static, the noise's name or ``None``.
      obs_shape: static, the shape of one observation.
      obs_mask: ``None``, or (after :func:`pad_observations`) a 0/1 array of ``obs_shape`` (batch axes first) that is
        1 on the components the emission map fills and 0 on the padding, which is 0 in every observation: a learner
        may read it to initialise its input layer as for the unpadded observation.
    """

    mdp: MDP
    emissions: jax.Array
    noise_scale: jax.Array
    noise_df: jax.Array
    noise_chol: jax.Array | None = None
    emission_kind: str = struct.field(pytree_node=False, default="state_info")
    noise_kind: str | None = struct.field(pytree_node=False, default=None)
    obs_shape: tuple[int, ...] = struct.field(pytree_node=False, default=())
    obs_mask: jax.Array | None = None

    @property
    def episodic(self) -> bool:
        return self.mdp.episodic

    @property
    def H(self) -> int | None:
        return self.mdp.H

    @property
    def horizon(self) -> jax.Array:
        return self.mdp.horizon

    @property
    def n_states(self) -> int:
        return self.mdp.n_states

    @property
    def n_actions(self) -> int:
        return self.mdp.n_actions

    @property
    def dtype(self) -> jnp.dtype:
        return self.mdp.dtype

    @property
    def info(self):
        """The MDP's static metadata."""
        return self.mdp.info

    @property
    def obs_dim(self) -> int:
        """Number of components of one observation."""
        return math.prod(self.obs_shape)

    def strip(self) -> "BlockMDP":
        """The same BlockMDP with the MDP's static metadata removed (see :meth:`MDP.strip`)."""
        return self.replace(mdp=self.mdp.strip())

    def __repr__(self) -> str:  # pragma: no cover - cosmetic
        return f"BlockMDP({self.mdp!r}, emission={self.emission_kind}, noise={self.noise_kind}, obs={self.obs_shape})"


def block_mdp(
    mdp: MDP,
    emission: str = "state_info",
    noise: str | None = None,
    *,
    key: jax.Array | None = None,
    **noise_params: Any,
) -> BlockMDP:
    """Build the BlockMDP of ``mdp`` with emission map ``emission`` and optional ``noise`` (paper App. A.2).

    Args:
      mdp: one MDP (stack BlockMDPs with :func:`jaxmdp.stack`).
      emission: ``"one_hot"``, ``"state_info"``, ``"image"``, ``"tensor"``, ``"linear_optimal"`` or
        ``"linear_random"`` (:func:`~jaxmdp.blockmdp.emission_maps.emission_table`).
      noise: ``None``, ``"gaussian"``, ``"correlated_gaussian"``, ``"student_t"`` or ``"correlated_student_t"``.
      key: needed by the linear emissions (their features) and the correlated noises (the Wishart covariance, drawn
        once here from ``fold_in(key, ...)``); ignored otherwise. The per-step noise comes from the step's key.
      noise_params: ``scale`` (all kinds) and ``df`` (the Student-t kinds); defaults in
        :data:`~jaxmdp.blockmdp.noise.NOISE_DEFAULTS`.

    Raises:
      ValueError: an unknown emission or noise (closest names listed), a parameter the noise does not take or out of
        range (``scale`` and ``df`` must be positive and finite), an emission the family cannot produce, a missing key.
    """
    emission = check_emission_kind(emission)
    noise = check_noise_kind(noise)
    params = noise_parameters(noise, noise_params)
    if noise in CORRELATED_NOISE_KINDS and key is None:
        raise ValueError(f"noise {noise!r} draws its Wishart covariance when the BlockMDP is made: pass key=...")
    table = emission_table(mdp, emission, key=key)
    obs_shape = tuple(table.shape[2:] if mdp.episodic else table.shape[1:])
    dtype = mdp.dtype
    chol = None
    if noise in CORRELATED_NOISE_KINDS:
        d = math.prod(obs_shape)
        chol = wishart_cholesky(jax.random.fold_in(key, _WISHART_STREAM), d, d, params["scale"], dtype)
    return BlockMDP(
        mdp=mdp,
        emissions=table,
        noise_scale=jnp.asarray(params.get("scale", 0.0), dtype),
        noise_df=jnp.asarray(params.get("df", 0.0), dtype),
        noise_chol=chol,
        emission_kind=emission,
        noise_kind=noise,
        obs_shape=obs_shape,
    )


def pad_observations(block: BlockMDP, obs_shape: tuple[int, ...]) -> BlockMDP:
    """``block`` observed through ``obs_shape``: every observation zero-padded at the end of each axis, with
    :attr:`BlockMDP.obs_mask` marking the original components (paper App. A.2's emission maps are unchanged on them).

    What it is for: BlockMDPs whose emission maps give observations of different shapes (``state_info`` of RiverSwim
    has one field, of DeepSea two) then stack into one batch, and run as one compiled program. The padding carries no
    information (it is 0 in every observation, noise included) and a deep agent of :mod:`agents.deep` rescales its
    input layer by the mask at ``init`` (:func:`agents.deep.networks.mask_input_layer`), so that its initialisation,
    and with it its learning, has the distribution it has on the unpadded observations.

    Raises ``ValueError`` for a batched BlockMDP, an ``obs_shape`` of another rank or smaller on some axis, and a
    correlated noise (its covariance is drawn at the original dimension).
    """
    obs_shape = tuple(int(n) for n in obs_shape)
    lead = 2 if block.episodic else 1
    if block.emissions.ndim != len(block.obs_shape) + lead:
        raise ValueError("pad_observations expects an unbatched BlockMDP; pad each member before jaxmdp.stack")
    if len(obs_shape) != len(block.obs_shape) or any(n < m for n, m in zip(obs_shape, block.obs_shape)):
        raise ValueError(f"obs_shape must have the observation's rank ({len(block.obs_shape)}) and be at least "
                         f"{block.obs_shape} on every axis; got {obs_shape}")
    if block.noise_kind in CORRELATED_NOISE_KINDS:
        raise ValueError(f"pad_observations: noise {block.noise_kind!r} is drawn with a covariance of the original "
                         f"dimension {block.obs_dim}; pad a BlockMDP without noise or with an uncorrelated one")
    if obs_shape == block.obs_shape:
        return block
    widths = [(0, 0)] * lead + [(0, n - m) for n, m in zip(obs_shape, block.obs_shape)]
    mask = np.ones(block.obs_shape, block.dtype) if block.obs_mask is None else np.asarray(block.obs_mask)
    # Padded on the host: jnp.pad would compile a small program per shape.
    return block.replace(
        emissions=jax.device_put(np.pad(np.asarray(block.emissions), widths)),
        obs_mask=jax.device_put(np.pad(mask, widths[lead:])),
        obs_shape=obs_shape,
    )


def noise_key(key: jax.Array) -> jax.Array:
    """The key of the emission noise drawn by :func:`jaxmdp.reset` / :func:`jaxmdp.step` called with ``key``."""
    return jax.random.fold_in(key, _NOISE_STREAM)


def observe(key: jax.Array | None, block: BlockMDP, state: jax.Array, h: jax.Array | int = 0) -> jax.Array:
    """The observation of ``state`` at in-episode step ``h``: ``table[h, state] + e`` (continuous: ``table[state] +
    e``, ``h`` ignored), ``e`` one noise draw from ``key`` (``key`` may be ``None`` without noise).

    Unbatched (``vmap`` it over a stacked BlockMDP). In an episodic MDP, ``h >= horizon`` (past the episode's last
    step) gives an all-zero array without noise, as the reference.
    """
    if block.emissions.ndim != len(block.obs_shape) + (2 if block.episodic else 1):
        raise ValueError("observe expects an unbatched BlockMDP; jax.vmap it over a stacked batch")
    if block.episodic:
        h = jnp.asarray(h, jnp.int32)
        row = block.emissions[jnp.minimum(h, block.emissions.shape[0] - 1), state]
    else:
        row = block.emissions[state]
    if block.noise_kind is not None:
        if key is None:
            raise ValueError(f"observe needs a key to draw the {block.noise_kind!r} noise")
        noise = sample_noise(
            key, block.noise_kind, block.obs_shape, block.noise_scale, block.noise_df, block.noise_chol, row.dtype
        )
        row = row + (noise if block.obs_mask is None else noise * block.obs_mask.astype(row.dtype))
    if block.episodic:
        row = jnp.where(h < block.mdp.horizon, row, jnp.zeros_like(row))
    return row
