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

__all__ = ["BlockMDP", "block_mdp", "observe", "noise_key"]

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
    """

    mdp: MDP
    emissions: jax.Array
    noise_scale: jax.Array
    noise_df: jax.Array
    noise_chol: jax.Array | None = None
    emission_kind: str = struct.field(pytree_node=False, default="state_info")
    noise_kind: str | None = struct.field(pytree_node=False, default=None)
    obs_shape: tuple[int, ...] = struct.field(pytree_node=False, default=())

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
        row = row + sample_noise(
            key, block.noise_kind, block.obs_shape, block.noise_scale, block.noise_df, block.noise_chol, row.dtype
        )
    if block.episodic:
        row = jnp.where(h < block.mdp.horizon, row, jnp.zeros_like(row))
    return row
