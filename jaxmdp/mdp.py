"""The MDP pytree and its construction from arrays.

An MDP ``M = (S, A, P, P0, R)`` (paper §2.1) is held as dense arrays:

* ``T[s, a, s']`` transition probabilities (rows sum to one),
* ``R[s, a] = sum_s' T[s, a, s'] * reward_mean[s, a, s']`` mean rewards,
* ``reward_mean[s, a, s']`` and ``reward_conc[s, a, s']``: the reward distribution of each transition, a
  Beta(``mean * conc``, ``(1 - mean) * conc``) when ``conc > 0`` and a point mass at ``mean`` when ``conc == 0``
  (Colosseum's families use exactly these two kinds, docs/families.md §1.5),
* ``P0[s]`` the starting distribution,
* ``succ[s, a, k]`` / ``succ_p[s, a, k]``: the same kernel as successor lists (``K`` entries per row, padded with
  zero-probability entries). They are derived from ``T`` by every constructor and let samplers and hitting-time
  solvers work in ``O(S A K)`` instead of ``O(S^2 A)``. Entries may repeat a state; probabilities then add up.
* ``start[j]`` / ``start_cdf[j]``: the sparse form of ``P0`` used by :func:`jaxmdp.reset` and auto-resets: the
  states of positive ``P0`` in increasing order and the cumulative sums ``sum_{s <= start[j]} P0[s]`` (the entries
  of ``cumsum(P0)`` at those states), padded to a static length ``K0`` by repeating the last start and its (total)
  cumulative sum.

The sparse fields are derived from the dense ones by every constructor and transform of the package
(:func:`successor_lists`, :func:`start_lists`); code that replaces ``T`` or ``P0`` by hand must rebuild them with
those functions.

Batching: ``state_mask`` and ``action_mask`` mark the real states and actions of an MDP padded by
:func:`jaxmdp.stack`; ``horizon`` is the (traced) episode length, while the static ``H`` is the length of time-indexed
arrays (equal to ``horizon`` for a single MDP, the largest horizon of a stacked batch). ``H is None`` means continuous.

``stochastic_rewards`` (static) records whether any reward is a Beta, so that deterministic-reward MDPs compile
samplers without Beta draws.

Static metadata (family, parameters, node labels, layout used for rendering) lives in the static :class:`MDPInfo`,
outside the traced leaves. Because static fields are part of a pytree's structure, library functions call
:meth:`MDP.strip` before their ``jit`` boundary so that MDPs that differ only in metadata share one compiled program.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp import struct
from jaxmdp._checks import check_int
from jaxmdp._memory import check_memory

__all__ = [
    "MDP",
    "MDPInfo",
    "custom_mdp",
    "successor_lists",
    "start_lists",
    "mdp_array_bytes",
    "custom_dense_bytes",
]

# Tolerance used to check that host-side arrays are stochastic.
_ROW_SUM_ATOL = 1e-5


@dataclasses.dataclass(frozen=True)
class MDPInfo:
    """Static, hashable metadata of an MDP (never traced).

    Attributes:
      family: registry name of the family (``"custom"`` for :func:`custom_mdp`).
      params: the construction parameters as ``(name, value)`` pairs, in the family's parameter order.
      node_labels: one label per state, e.g. ``"X=0,Y=2,Dir=LEFT"`` (Colosseum's ``str(node)``).
      node_fields: names of the node fields (the ``StateInfo`` vector).
      node_values: the node fields of every state as integers (enums by value).
      layout: family-specific data used by the text renderer, as ``(key, value)`` pairs.
      members: for a stacked batch, the infos of its members.
    """

    family: str = "custom"
    params: tuple[tuple[str, Any], ...] = ()
    node_labels: tuple[str, ...] = ()
    node_fields: tuple[str, ...] = ()
    node_values: tuple[tuple[int, ...], ...] = ()
    layout: tuple[tuple[str, Any], ...] = ()
    members: tuple["MDPInfo", ...] = ()

    def param(self, name: str, default: Any = None) -> Any:
        """The value of construction parameter ``name``."""
        return dict(self.params).get(name, default)

    def layout_value(self, name: str, default: Any = None) -> Any:
        """The value of layout entry ``name``."""
        return dict(self.layout).get(name, default)


_EMPTY_INFO = MDPInfo()


@struct.dataclass
class MDP:
    """A finite MDP as dense arrays (see the module docstring for every field)."""

    T: jax.Array
    R: jax.Array
    P0: jax.Array
    reward_mean: jax.Array
    reward_conc: jax.Array
    succ: jax.Array
    succ_p: jax.Array
    start: jax.Array
    start_cdf: jax.Array
    state_mask: jax.Array
    action_mask: jax.Array
    horizon: jax.Array
    H: int | None = struct.field(pytree_node=False, default=None)
    info: MDPInfo = struct.field(pytree_node=False, default=_EMPTY_INFO)
    #: Static: whether some transition has a Beta reward. False lets samplers skip the Beta draw at compile time;
    #: True is always correct (point masses are returned as their value either way).
    stochastic_rewards: bool = struct.field(pytree_node=False, default=True)

    @property
    def n_states(self) -> int:
        """Number of states ``S`` of the arrays (padding included)."""
        return self.T.shape[-1]

    @property
    def n_actions(self) -> int:
        """Number of actions ``A`` of the arrays (padding included)."""
        return self.T.shape[-2]

    @property
    def max_successors(self) -> int:
        """Length ``K`` of the successor lists."""
        return self.succ.shape[-1]

    @property
    def max_starts(self) -> int:
        """Length ``K0`` of the start list (the number of start states, or the largest one of a stacked batch)."""
        return self.start.shape[-1]

    @property
    def episodic(self) -> bool:
        """Whether the MDP is episodic (has a horizon)."""
        return self.H is not None

    @property
    def dtype(self) -> jnp.dtype:
        """Floating dtype of the MDP's arrays."""
        return self.T.dtype

    @property
    def reward_alpha(self) -> jax.Array:
        """Beta ``alpha`` of each transition's reward (0 for point masses)."""
        return self.reward_mean * self.reward_conc

    @property
    def reward_beta(self) -> jax.Array:
        """Beta ``beta`` of each transition's reward (0 for point masses)."""
        return (1.0 - self.reward_mean) * self.reward_conc

    def strip(self) -> "MDP":
        """The same MDP without static metadata, so that jitted code compiles once per shape."""
        return self.replace(info=_EMPTY_INFO)

    def astype(self, dtype: Any) -> "MDP":
        """The MDP with its floating arrays cast to ``dtype`` (e.g. ``jnp.float64`` with x64 enabled)."""
        cast = lambda x: x.astype(dtype)  # noqa: E731
        return self.replace(
            T=cast(self.T),
            R=cast(self.R),
            P0=cast(self.P0),
            reward_mean=cast(self.reward_mean),
            reward_conc=cast(self.reward_conc),
            succ_p=cast(self.succ_p),
            start_cdf=cast(self.start_cdf),
        )

    def __repr__(self) -> str:  # pragma: no cover - cosmetic
        kind = f"episodic H={self.H}" if self.episodic else "continuous"
        batch = self.T.shape[:-3]
        b = f", batch={batch}" if batch else ""
        return (
            f"MDP({self.info.family}, S={self.n_states}, A={self.n_actions}, K={self.max_successors}, "
            f"{kind}{b}, dtype={self.dtype})"
        )


def mdp_array_bytes(S: int, A: int, K: int, itemsize: int, n_starts: int = 1) -> int:
    """Bytes of the arrays of one :class:`MDP` with ``S`` states, ``A`` actions, ``K`` successors per row and
    ``n_starts`` start states in a dtype of ``itemsize`` bytes: the three dense ``[S, A, S]`` arrays, ``R``, the
    successor lists, ``P0``, the start lists and the masks."""
    S, A, K, b = int(S), int(A), int(K), int(itemsize)
    return 3 * S * A * S * b + S * A * b + S * A * K * (4 + b) + S * b + n_starts * (4 + b) + S + A + 4


def custom_dense_bytes(S: int, A: int, itemsize: int) -> int:
    """Peak bytes :func:`custom_mdp` holds for an ``[S, A, S]`` kernel in a dtype of ``itemsize`` bytes, successor
    lists aside (:func:`successor_lists` checks those once it knows ``K``).

    Per entry of ``[S, A, S]``: 32 bytes of float64 work arrays (``T`` as given and normalised, ``reward_mean``,
    ``reward_conc``; the transient products and boolean masks of the checks fit in the same room, as they are freed
    before the casts), the three casts to the dtype and their copies on the device (``6 * itemsize``); the ``[S, A]``
    and ``[S]`` arrays likewise. A family's construction (:func:`jaxmdp.mdp_families.build_mdp`) passes its three
    float64 arrays uncopied, so the same count bounds it.
    """
    S, A, b = int(S), int(A), int(itemsize)
    return (32 + 6 * b) * S * A * S + (24 + 2 * b) * S * A + (16 + 2 * b) * S


def successor_lists(T: np.ndarray, K: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Host-side successor lists of a dense kernel.

    Returns ``(succ, succ_p)`` of shape ``[S, A, K]`` with, for every row, the states of positive probability in
    increasing order, padded with ``(s, 0.0)`` entries (the row's own state, probability zero). ``K`` defaults to the
    largest number of successors of any row.
    """
    T = np.asarray(T)
    S, A, _ = T.shape
    nnz = (T > 0).sum(-1)
    k_needed = max(int(nnz.max()) if nnz.size else 1, 1)
    K = k_needed if K is None else K
    if K < k_needed:
        raise ValueError(f"K={K} is smaller than the largest number of successors ({k_needed})")
    # int64 indices and their int32 copy, the probabilities and their cast by the caller.
    check_memory(
        S * A * K * (12 + 2 * T.dtype.itemsize),
        "the successor lists",
        {"S": S, "A": A, "K": K},
        remedy="use a smaller MDP or one with fewer successors per row, or a machine with more memory",
    )
    succ = np.broadcast_to(np.arange(S)[:, None, None], (S, A, K)).copy()
    succ_p = np.zeros((S, A, K), dtype=T.dtype)
    for s in range(S):
        for a in range(A):
            (idx,) = np.nonzero(T[s, a] > 0)
            succ[s, a, : idx.size] = idx
            succ_p[s, a, : idx.size] = T[s, a, idx]
    return succ.astype(np.int32), succ_p


def start_lists(P0: Any, n_starts: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Host-side sparse start distribution ``(start, start_cdf)`` of a concrete ``P0`` (see the module docstring).

    ``start`` lists the states with ``P0 > 0`` in increasing order, padded to ``n_starts`` entries (default: the number
    of start states) by repeating the last one; ``start_cdf`` holds ``cumsum(P0)`` at those states (summed in float64,
    stored in ``P0``'s dtype), so its last entry is the total mass.
    """
    P0 = np.asarray(P0)
    (idx,) = np.nonzero(P0 > 0)
    if idx.size == 0:
        raise ValueError("P0 must have at least one state of positive probability")
    n_starts = idx.size if n_starts is None else n_starts
    if n_starts < idx.size:
        raise ValueError(f"n_starts must be at least the number of start states ({idx.size}); got {n_starts}")
    start = np.concatenate([idx, np.full(n_starts - idx.size, idx[-1])]).astype(np.int32)
    return start, np.cumsum(P0.astype(np.float64))[start].astype(P0.dtype)


def _check_finite(name: str, x: np.ndarray) -> None:
    if not np.all(np.isfinite(x)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(x))[0])
        raise ValueError(f"{name} must be finite; found {x[bad]} at index {bad}")


def custom_mdp(
    T: Any,
    R: Any | None = None,
    P0: Any | None = None,
    H: int | None = None,
    *,
    reward_mean: Any | None = None,
    reward_conc: Any | None = None,
    dtype: Any = jnp.float32,
    info: MDPInfo | None = None,
) -> MDP:
    """Build an :class:`MDP` from arrays, validating every input.

    Args:
      T: ``[S, A, S]`` transition probabilities; every row must be a distribution.
      R: ``[S, A]`` mean rewards. If ``reward_mean`` is omitted the reward of ``(s, a)`` is a point mass at
        ``R[s, a]`` whatever the next state. If both are given they must agree: ``R = sum_s' T * reward_mean``.
      P0: ``[S]`` starting distribution (default: state 0 with probability one).
      H: episode length for an episodic MDP (a positive integer), or ``None`` for a continuous one.
      reward_mean: ``[S, A, S]`` mean reward of each transition (optional).
      reward_conc: ``[S, A, S]`` Beta concentration ``alpha + beta`` of each transition's reward; ``0`` is a point
        mass at the mean (default: all point masses). Where positive, the mean must lie strictly inside (0, 1).
      dtype: floating dtype of the arrays (``float32`` by default).
      info: static metadata (default: family ``"custom"`` and labels ``"s=<index>"``).

    Raises:
      ValueError: naming the offending argument, for wrong shapes, NaN/inf, negative probabilities, rows that do not
        sum to one (the first offending ``(s, a)`` is reported), a non-positive ``H`` or invalid reward parameters;
        :class:`~jaxmdp.NotEnoughMemory` (a ``ValueError``) before converting anything when the arrays of
        ``S`` states and ``A`` actions cannot fit in the memory available (:func:`custom_dense_bytes`).
    """
    shape = np.shape(T)
    if len(shape) != 3 or shape[0] != shape[2] or shape[0] < 1 or shape[1] < 1:
        raise ValueError(f"T must have shape [S, A, S] with S, A >= 1; got shape {tuple(shape)}")
    S, A, _ = shape
    np_dtype = np.dtype(jnp.dtype(dtype))
    check_memory(
        custom_dense_bytes(S, A, np_dtype.itemsize),
        "jaxmdp.custom_mdp",
        {"S": S, "A": A, "dtype": np_dtype.name},
        detail="dense [S, A, S] arrays",
        device_bytes=mdp_array_bytes(S, A, 1, np_dtype.itemsize),
        remedy="use a smaller MDP, a narrower dtype (float32 rather than float64), or a machine with more memory",
    )
    T = np.asarray(T, dtype=np.float64)
    _check_finite("T", T)
    if np.any(T < 0):
        s, a, t = (int(i) for i in np.argwhere(T < 0)[0])
        raise ValueError(f"T must be non-negative; T[{s}, {a}, {t}] = {T[s, a, t]}")
    sums = T.sum(-1)
    bad = np.abs(sums - 1.0) > _ROW_SUM_ATOL
    if np.any(bad):
        s, a = (int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"every row of T must sum to 1; row (s={s}, a={a}) sums to {sums[s, a]:.8g}")
    T = T / sums[..., None]

    if reward_mean is not None:
        reward_mean = np.asarray(reward_mean, dtype=np.float64)
        if reward_mean.shape != (S, A, S):
            raise ValueError(f"reward_mean must have shape {(S, A, S)}; got {reward_mean.shape}")
        _check_finite("reward_mean", reward_mean)
        R_from_mean = (T * reward_mean).sum(-1)
        if R is not None:
            R = np.asarray(R, dtype=np.float64)
            if R.shape != (S, A):
                raise ValueError(f"R must have shape {(S, A)}; got {R.shape}")
            if not np.allclose(R, R_from_mean, atol=1e-5):
                s, a = (int(i) for i in np.argwhere(~np.isclose(R, R_from_mean, atol=1e-5))[0])
                raise ValueError(
                    f"R disagrees with sum_s' T * reward_mean at (s={s}, a={a}): {R[s, a]} vs {R_from_mean[s, a]}"
                )
        R = R_from_mean
    else:
        if R is None:
            raise ValueError("one of R or reward_mean must be given")
        R = np.asarray(R, dtype=np.float64)
        if R.shape != (S, A):
            raise ValueError(f"R must have shape {(S, A)}; got {R.shape}")
        _check_finite("R", R)
        reward_mean = np.broadcast_to(R[:, :, None], (S, A, S)).copy()

    if reward_conc is None:
        reward_conc = np.zeros((S, A, S))
    else:
        reward_conc = np.asarray(reward_conc, dtype=np.float64)
        if reward_conc.shape != (S, A, S):
            raise ValueError(f"reward_conc must have shape {(S, A, S)}; got {reward_conc.shape}")
        _check_finite("reward_conc", reward_conc)
        if np.any(reward_conc < 0):
            raise ValueError("reward_conc must be >= 0 (0 means a point-mass reward)")
        beta_entries = (reward_conc > 0) & (T > 0)
        m = reward_mean[beta_entries]
        if np.any((m <= 0) | (m >= 1)):
            raise ValueError("a Beta reward (reward_conc > 0) needs a mean strictly inside (0, 1)")

    if P0 is None:
        P0 = np.zeros(S)
        P0[0] = 1.0
    P0 = np.asarray(P0, dtype=np.float64)
    if P0.shape != (S,):
        raise ValueError(f"P0 must have shape {(S,)}; got {P0.shape}")
    _check_finite("P0", P0)
    if np.any(P0 < 0) or abs(P0.sum() - 1.0) > _ROW_SUM_ATOL:
        raise ValueError(f"P0 must be a probability distribution (non-negative, sum 1); sum is {P0.sum():.8g}")
    P0 = P0 / P0.sum()

    if H is not None:
        check_int("H", H, context=" (or None for a continuous MDP)")
        H = int(H)

    if info is None:
        info = MDPInfo(node_labels=tuple(f"s={i}" for i in range(S)))

    succ, succ_p = successor_lists(T)
    start, start_cdf = start_lists(P0.astype(np_dtype))
    # Every leaf is cast on the host and transferred in one device_put: a jnp.asarray(x, dtype=...) per leaf would
    # compile a small conversion program per leaf and shape.
    leaves = jax.device_put(
        dict(
            T=T.astype(np_dtype),
            R=R.astype(np_dtype),
            P0=P0.astype(np_dtype),
            reward_mean=reward_mean.astype(np_dtype),
            reward_conc=reward_conc.astype(np_dtype),
            succ=succ,
            succ_p=succ_p.astype(np_dtype),
            start=start,
            start_cdf=start_cdf,
            state_mask=np.ones((S,), dtype=bool),
            action_mask=np.ones((A,), dtype=bool),
            horizon=np.asarray(H if H is not None else 0, dtype=np.int32),
        )
    )
    return MDP(
        **leaves,
        H=H,
        info=info,
        stochastic_rewards=bool(np.any(reward_conc[T > 0] > 0)),
    )
