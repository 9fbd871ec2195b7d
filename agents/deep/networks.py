"""The multilayer perceptrons shared by the deep agents (bsuite's baselines: ReLU hidden layers; docs/agents.md §7)."""

from __future__ import annotations

from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

__all__ = ["MLP"]


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
