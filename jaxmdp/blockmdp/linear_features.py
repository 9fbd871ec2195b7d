"""Random features in whose span a given value function lies exactly (paper App. A.2, "linear optimal value" and
"linear random value" emission maps; benchmark.md §5).

For a value vector ``v`` of ``N`` entries and ``d`` features: draw ``Psi ~ N(0, 1)^{N x d}`` and set its column 0 to
``1`` and column 1 to ``v``; draw ``W ~ N(0, 1)^{N x d}`` with column 0 set to ``1``; the features are the columns of
``P W``, ``P`` the orthogonal projection onto the column space of ``Psi``, each normalised to unit Euclidean norm.
``P W`` spans the column space of ``Psi`` (almost surely), which contains ``v``, so ``v = Phi theta`` for some
``theta``: the value is linear in the features.

``P`` is applied as ``Q Q^T`` with ``Q`` from a reduced QR decomposition of ``Psi`` (in float64). When ``Psi`` has full
column rank this is the reference's ``Psi (Psi^T Psi)^{-1} Psi^T``; unlike the explicit inverse it stays valid when
``N < d`` (then ``P = I``) or when ``v`` is constant (columns 0 and 1 collinear), where the reference's inverse is
singular.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["n_linear_features", "linear_value_features"]

#: Smallest number of linear features (the reference's ``config.get_min_linear_feature_dim()``).
MIN_LINEAR_FEATURES = 10


def n_linear_features(n_states: int) -> int:
    """``d = max(10, floor(0.1 S))`` (benchmark.md §5)."""
    return max(MIN_LINEAR_FEATURES, int(0.1 * n_states))


def linear_value_features(key: jax.Array, v: np.ndarray, d: int) -> np.ndarray:
    """``[N, d]`` unit-norm features (float64) whose span contains the length-``N`` vector ``v`` (module docstring).

    Both Gaussian matrices come from ``key`` (standard normal float32 draws, widened to float64)."""
    v = np.asarray(v, np.float64).ravel()
    if not np.all(np.isfinite(v)):
        raise ValueError("the value vector of a linear emission must be finite")
    N = v.size
    k_psi, k_w = jax.random.split(key)
    psi = np.asarray(jax.random.normal(k_psi, (N, d), jnp.float32), np.float64)
    psi[:, 0] = 1.0
    psi[:, 1] = v
    W = np.asarray(jax.random.normal(k_w, (N, d), jnp.float32), np.float64)
    W[:, 0] = 1.0
    Q, _ = np.linalg.qr(psi)
    features = Q @ (Q.T @ W)
    return features / np.linalg.norm(features, axis=0, keepdims=True)
