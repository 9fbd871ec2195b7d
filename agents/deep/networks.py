"""The multilayer perceptrons shared by the deep agents (bsuite's baselines: ReLU hidden layers; docs/agents.md §7),
and an orthogonal initialiser that is safe to ``vmap`` on jaxlib 0.10.2's CPU backend."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp.jaxlib_workarounds.linalg import qr

__all__ = ["MLP", "orthogonal"]


class MLP(nn.Module):
    """``x -> flatten -> [Dense(w) -> ReLU for w in hidden] -> Dense(n_outputs)``.

    ``n_outputs=None`` leaves out the linear output layer (a torso), and ``activate_final`` then decides whether the
    last hidden layer keeps its ReLU (the actor-critics' torso does). The observation is flattened over all but
    ``batch_dims`` leading axes, so images and tensors work as they are.
    """

    hidden: Sequence[int]
    n_outputs: int | None = None
    activate_final: bool = True
    batch_dims: int = 0

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        x = jnp.reshape(x, x.shape[: self.batch_dims] + (-1,)).astype(jnp.float32)
        for i, width in enumerate(self.hidden):
            x = nn.Dense(width)(x)
            if i < len(self.hidden) - 1 or self.n_outputs is not None or self.activate_final:
                x = nn.relu(x)
        if self.n_outputs is not None:
            x = nn.Dense(self.n_outputs)(x)
        return x


def orthogonal(scale: float = 1.0, column_axis: int = -1) -> Callable[..., jax.Array]:
    """``jax.nn.initializers.orthogonal(scale, column_axis)`` (flax's default for recurrent kernels), draw for draw:
    a uniformly distributed (Haar) orthogonal matrix, the ``Q`` of the QR decomposition of a standard normal matrix
    with the signs of ``diag(R)`` moved into ``Q`` (Mezzadri 2007, "How to generate random matrices from the
    classical compact groups"), times ``scale``.

    The QR is :func:`jaxmdp.jaxlib_workarounds.linalg.qr`: an agent initialised under ``vmap`` (every runner grid)
    would otherwise run one batched LAPACK QR per kernel, which deadlocks jaxlib 0.10.2's CPU thread pool when two of
    them run at once (observed: the recurrent actor-critic's learning probes).
    """

    def init(key: jax.Array, shape: Sequence[int], dtype: Any = jnp.float32) -> jax.Array:
        if len(shape) < 2:
            raise ValueError(f"orthogonal initialiser: shape must have at least 2 axes; got {tuple(shape)}")
        n_cols = shape[column_axis]
        n_rows = math.prod(shape) // n_cols
        z = jax.random.normal(key, (max(n_rows, n_cols), min(n_rows, n_cols)), dtype)
        q, r = qr(z)
        q = q * jnp.sign(jnp.diagonal(r))[None, :]
        q = q.T if n_rows < n_cols else q
        q = jnp.reshape(q, tuple(np.delete(np.asarray(shape), column_axis)) + (n_cols,))
        return jnp.asarray(scale, dtype) * jnp.moveaxis(q, -1, column_axis)

    return init
