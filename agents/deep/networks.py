"""The multilayer perceptrons shared by the deep agents (bsuite's baselines: ReLU hidden layers; docs/agents.md §7),
an ensemble of them evaluated as batched matrix products over its heads, and an orthogonal initialiser that is safe
to ``vmap`` on jaxlib 0.10.2's CPU backend."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp

from jaxmdp.jaxlib_workarounds.linalg import one_at_a_time

__all__ = ["MLP", "ensemble_apply", "mask_input_layer", "orthogonal"]


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


def ensemble_apply(params: Any, x: jax.Array) -> jax.Array:
    """``K`` heads of an :class:`MLP` with a linear output layer (``n_outputs`` set), all on the same batch:
    ``out[k, i] = MLP(params[k])(x[i])``, ``[K, B, n_outputs]`` for ``params`` with a leading head axis ``K`` on every
    leaf (a ``vmap`` of ``MLP.init``) and ``x`` of shape ``[B, *obs]``.

    Each layer is one matrix product batched over the heads, ``h_k <- relu(W_k^T h_k + b_k)``, its activations laid
    out head-major and feature-major, ``[K, width, B]``, from the first layer on (which reads the shared ``x`` once for
    all heads); the output is transposed to ``[K, B, n_outputs]`` at the end. Why this layout: ``jax.vmap`` of
    ``MLP.apply`` over heads and batch gives batch-major activations, and even head-major ``[K, B, width]`` ones
    (bsuite's width, 50, as the products' minor dimension) are transposed and copied around every batched product
    by XLA's CPU backend, forward and backward; ``[K, width, B]``, the batch (128) minor, moves none and runs
    BootDQN's SGD step about 1.2x faster (docs/performance.md, Deep agents; tests/test_runner_planning.py).
    """
    layers = params["params"]
    names = sorted(layers, key=lambda name: int(name.rsplit("_", 1)[1]))  # Dense_0, Dense_1, ... (Dense_10 after 9)
    h = jnp.reshape(x, (x.shape[0], -1)).astype(jnp.float32)
    first = layers[names[0]]
    h = jnp.einsum("kio,bi->kob", first["kernel"], h) + first["bias"][:, :, None]
    for name in names[1:]:
        h = jnp.einsum("kio,kib->kob", layers[name]["kernel"], nn.relu(h)) + layers[name]["bias"][:, :, None]
    return jnp.swapaxes(h, 1, 2)


def mask_input_layer(params: Any, mask: jax.Array | None, path: Sequence[str]) -> Any:
    """``params`` with the input layer at ``path`` (its ``kernel``, ``[..., d, width]`` with any leading head axes)
    initialised as for the observation's unpadded components: ``kernel * m[:, None] * sqrt(d / sum(m))`` for the
    flattened 0/1 ``mask`` ``m`` of :attr:`jaxmdp.BlockMDP.obs_mask` (``None``: ``params`` unchanged).

    Why this is exact: flax's default ``lecun_normal`` kernel is ``sqrt(1 / fan_in) / c`` times a standard normal
    truncated to ``[-2, 2]``, each entry independent, so the kept rows of a draw at fan-in ``d``, scaled by
    ``sqrt(d / n)``, are distributed as a draw at the true fan-in ``n``. The padded rows are zeroed; they meet only
    zero inputs, so they get no gradient (Adam moves nothing without one) and the network computes, and learns, what
    it would on the unpadded observations (a padded member's initialisation has the unpadded one's distribution; from
    the same parameters the same updates, up to rounding).
    """
    if mask is None:
        return params
    m = jnp.reshape(mask, (-1,)).astype(jnp.float32)
    scale = m * jnp.sqrt(m.shape[0] / jnp.maximum(jnp.sum(m), 1.0))

    def rescale(node: Any, keys: Sequence[str]) -> Any:
        if not keys:
            return {**node, "kernel": node["kernel"] * scale[:, None].astype(node["kernel"].dtype)}
        return {**node, keys[0]: rescale(node[keys[0]], keys[1:])}

    return rescale(params, tuple(path))


def orthogonal(scale: float = 1.0, column_axis: int = -1) -> Callable[..., jax.Array]:
    """``jax.nn.initializers.orthogonal(scale, column_axis)`` (flax's default for recurrent kernels: a uniformly
    distributed orthogonal matrix, the sign-corrected ``Q`` of the QR decomposition of a standard normal matrix,
    Mezzadri 2007), draw for draw, with each key's draw wrapped in
    :func:`jaxmdp.jaxlib_workarounds.linalg.one_at_a_time`: an agent initialised under ``vmap`` (every runner grid)
    would otherwise run one batched LAPACK QR per kernel, which deadlocks jaxlib 0.10.2's CPU thread pool when two of
    them run at once (observed: the recurrent actor-critic's learning probes)."""
    init = jax.nn.initializers.orthogonal(scale, column_axis)

    def init_one_key_at_a_time(key: jax.Array, shape: Sequence[int], dtype: Any = jnp.float32) -> jax.Array:
        return one_at_a_time(lambda k: init(k, shape, dtype))(key)

    return init_one_key_at_a_time
