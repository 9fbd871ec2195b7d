"""The result type shared by every hardness measure."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmdp import struct

__all__ = ["MeasureResult"]


class MeasureResult(struct.PyTreeNode):
    """A hardness measure with its reliability flags (scalars, or arrays under ``vmap``).

    Attributes:
      value: the measure. ``+inf`` when it is infinite (a target no policy reaches) or when the solver could not
        certify it within its iteration budget; never a wrong finite number.
      converged: the solver met its stopping rule or certificate within the budget. ``value = inf`` with
        ``converged = True`` means *certified infinite*; with ``converged = False`` it means *unknown*.
      finite: ``isfinite(value)``.
    """

    value: jax.Array
    converged: jax.Array
    finite: jax.Array

    @classmethod
    def make(cls, value: jax.Array, converged: jax.Array) -> "MeasureResult":
        """A result whose ``value`` becomes ``inf`` unless ``converged``."""
        converged = jnp.asarray(converged, bool)
        value = jnp.where(converged, value, jnp.inf)
        return cls(value=value, converged=converged, finite=jnp.isfinite(value))
