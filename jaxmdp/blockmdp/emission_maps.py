"""Emission maps: the observation of every state as one table (paper §3.1 and App. A.2; benchmark.md §5).

:func:`emission_table` returns ``[S, *obs_shape]`` for a continuous MDP and ``[H, S, *obs_shape]`` for an episodic
one, row ``[h, s]`` being the observation of state ``s`` at in-episode step ``h``:

* ``"one_hot"``: the length-``S`` indicator of the state; it carries no time information (every ``h`` has the same
  rows), as in the reference;
* ``"state_info"``: the family's node fields as floats, in declaration order (RiverSwim ``(X)``, DeepSea ``(X, Y)``,
  MiniGrid ``(X, Y, Dir)``, Taxi ``(X, Y, XPass, YPass, XDest, YDest)``, ...); episodic: ``(h, fields...)``;
* ``"image"``: the family's text rendering of the state (:func:`jaxmdp.render` without the episodic header) with each
  symbol replaced by its index in the family's symbol list, a ``rows x cols`` matrix; episodic: one row filled with
  ``h`` on top;
* ``"tensor"``: the same grid one-hot over the symbols, ``rows x cols x n_symbols``; episodic: one more channel
  (last) filled with ``h``;
* ``"linear_optimal"`` / ``"linear_random"``: ``d = max(10, floor(0.1 S))`` random features in whose span lies the
  optimal value ``V*`` (resp. the uniformly random policy's value ``V^u``) exactly
  (:mod:`jaxmdp.blockmdp.linear_features`). Continuous: the ``gamma = 0.99`` discounted values; episodic: the
  finite-horizon values ``V_h(s)`` of every ``(h, s)``, the features drawn over ``h = 0 .. H`` (terminal row
  included, as the reference) and rows ``0 .. H-1`` returned. They need an explicit ``key``.

Departures from the reference (benchmark.md §5 quirks): image and tensor render the *queried* state (the reference's
MiniGrid renders the MDP's current one, so every state looked the same); an episodic grid is never widened with
``X`` columns for the time header (the header is dropped anyway; the reference widened grids narrower than
``2 + len(str(h))`` columns and failed on families without an ``X`` symbol); the linear features come from the given
key, not numpy's global generator.

Tables are built host-side (the renderers are Python) in the MDP's dtype; the rows of padded states are zero.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp import dynamic_programming as dp
from jaxmdp._checks import did_you_mean
from jaxmdp._memory import check_memory
from jaxmdp.blockmdp.linear_features import linear_value_features, n_linear_features
from jaxmdp.mdp import MDP
from jaxmdp.render import render_grid

__all__ = [
    "EMISSION_KINDS",
    "check_emission_kind",
    "emission_table",
    "emission_shape",
    "emission_bytes",
    "register_symbols",
    "family_symbols",
]

#: The emission kinds (paper App. A.2; benchmark.md §5).
EMISSION_KINDS = ("one_hot", "state_info", "image", "tensor", "linear_optimal", "linear_random")
#: Kinds that every MDP supports (the others need the family's node fields or its renderer and symbols).
GENERIC_KINDS = ("one_hot", "linear_optimal", "linear_random")
#: Discount of the values the continuous linear maps are built on (benchmark.md §5: discounted value iteration).
LINEAR_GAMMA = 0.99

# Each family's rendering symbols; a symbol's index is its code in the image map and its channel in the tensor map
# (benchmark.md §5, families.md §2; MiniGridDoorKey is ours, from its renderer).
_SYMBOLS: dict[str, tuple[str, ...]] = {
    "RiverSwim": (" ", "A", "S", "G"),
    "DeepSea": ("A", " "),
    "SimpleGrid": (" ", "A", "+", "-"),
    "FrozenLake": ("A", "F", "H", "G"),
    "MiniGridEmpty": (" ", ">", "<", "v", "^", "G"),
    "MiniGridRooms": (" ", ">", "<", "v", "^", "G", "W"),
    "Taxi": (" ", "A", "X", "D", "P"),
    "MiniGridDoorKey": (" ", ">", "<", "v", "^", "G", "W", "K", "C", "O"),
}


def register_symbols(family: str, symbols: Sequence[str]) -> None:
    """Register the symbol list of ``family``'s text renderer (needed by the image and tensor maps)."""
    symbols = tuple(symbols)
    if not symbols or len(set(symbols)) != len(symbols) or not all(isinstance(s, str) and s for s in symbols):
        raise ValueError(f"symbols must be distinct non-empty strings; got {symbols!r}")
    _SYMBOLS[family] = symbols


def family_symbols(family: str) -> tuple[str, ...] | None:
    """The symbol list of ``family`` (``None`` if it has none)."""
    return _SYMBOLS.get(family)


def check_emission_kind(kind: str) -> str:
    """``kind`` if it is a known emission kind; otherwise a ``ValueError`` listing the closest names."""
    if kind in EMISSION_KINDS:
        return kind
    raise ValueError(f"unknown emission {kind!r}{did_you_mean(kind, EMISSION_KINDS)} "
                     f"Known: {', '.join(map(repr, EMISSION_KINDS))}")


def _unsupported(mdp: MDP, kind: str, needs: str) -> ValueError:
    return ValueError(
        f"emission {kind!r} needs {needs}, which this MDP (family {mdp.info.family!r}) lacks (a custom MDP, or metadata "
        f"removed by MDP.strip()); kinds that work for any MDP: {', '.join(map(repr, GENERIC_KINDS))}"
    )


def _node_fields(mdp: MDP, kind: str) -> np.ndarray:
    values = mdp.info.node_values
    if not values or len(values) > mdp.n_states:
        raise _unsupported(mdp, kind, "the family's node fields (MDPInfo.node_values)")
    return np.asarray(values, np.float64).reshape(len(values), -1)


def _symbol_codes(mdp: MDP, kind: str) -> tuple[np.ndarray, int]:
    """``[S_real, rows, cols]`` symbol codes of every state's rendering, and the number of symbols."""
    family = mdp.info.family
    symbols = _SYMBOLS.get(family)
    needs = "the family's text renderer and its symbol list (jaxmdp.blockmdp.register_symbols)"
    if symbols is None or not mdp.info.node_values:
        raise _unsupported(mdp, kind, needs)
    code = {s: i for i, s in enumerate(symbols)}
    grids = []
    for s in range(len(mdp.info.node_values)):
        try:
            grid = render_grid(mdp, s)
        except ValueError as e:  # the family registered symbols but no renderer
            raise _unsupported(mdp, kind, needs) from e
        try:
            grids.append([[code[c] for c in row] for row in grid])
        except KeyError as e:
            raise ValueError(f"{family} rendered symbol {e.args[0]!r}, not in its symbol list {symbols}") from None
    return np.asarray(grids, np.int64), len(symbols)


def _values(mdp: MDP, kind: str) -> np.ndarray:
    """``V*`` (``linear_optimal``) or ``V^u`` (``linear_random``): ``[S]`` discounted, or ``[H + 1, S]`` episodic."""
    m = mdp.strip()
    if kind == "linear_optimal":
        if m.episodic:
            V = jax.jit(lambda m: dp.finite_horizon_value_iteration(m)[1])(m)
        else:
            V = jax.jit(lambda m: dp.solve_discounted(m, LINEAR_GAMMA).V)(m)
    elif m.episodic:
        V = jax.jit(lambda m: dp.finite_horizon_policy_evaluation(m, dp.uniform_policy(m))[1])(m)
    else:
        V = jax.jit(lambda m: dp.policy_evaluation(m, dp.uniform_policy(m), LINEAR_GAMMA)[1])(m)
    return np.asarray(V, np.float64)


def _state_table(mdp: MDP, kind: str, key: jax.Array | None) -> np.ndarray:
    """The table without the time axis, ``[S_real, ...]`` (linear: ``[H + 1, S, d]`` when episodic)."""
    if kind == "one_hot":
        return np.eye(mdp.n_states)
    if kind == "state_info":
        return _node_fields(mdp, kind)
    if kind in ("image", "tensor"):
        codes, n_symbols = _symbol_codes(mdp, kind)
        return codes.astype(np.float64) if kind == "image" else np.eye(n_symbols)[codes]
    if key is None:
        raise ValueError(f"emission {kind!r} draws random features: pass key=jax.random.key(...)")
    v = _values(mdp, kind)
    n_real = int(np.sum(np.asarray(mdp.state_mask)))
    features = linear_value_features(key, v, n_linear_features(n_real))
    return features.reshape(*v.shape, -1)


def _add_time(table: np.ndarray, kind: str, H: int) -> np.ndarray:
    """``[H, S, *obs]`` from the time-free ``[S, *obs]`` table (benchmark.md §5's episodic conventions)."""
    S = table.shape[0]
    h = np.arange(H, dtype=np.float64)
    rows = np.broadcast_to(table, (H, *table.shape))
    if kind == "one_hot":
        return rows
    if kind == "state_info":
        return np.concatenate([np.broadcast_to(h[:, None, None], (H, S, 1)), rows], axis=-1)
    if kind == "image":
        top = np.broadcast_to(h[:, None, None, None], (H, S, 1, table.shape[-1]))
        return np.concatenate([top, rows], axis=-2)
    # tensor
    return np.concatenate([rows, np.broadcast_to(h[:, None, None, None, None], (*rows.shape[:-1], 1))], axis=-1)


def _grid_shape(mdp: MDP) -> tuple[int, int] | None:
    """``(rows, cols)`` of the family's rendering (of its first state), or None when it has none."""
    if _SYMBOLS.get(mdp.info.family) is None or not mdp.info.node_values:
        return None
    try:
        grid = render_grid(mdp, 0)
    except ValueError:
        return None
    return len(grid), len(grid[0]) if grid else 0


def emission_shape(mdp: MDP, kind: str) -> tuple[int, ...] | None:
    """The shape of one observation under ``kind`` (time channel included when episodic), found without building
    the table; None when the MDP cannot produce ``kind`` (:func:`emission_table` then says why)."""
    S = mdp.n_states
    t = 1 if mdp.episodic else 0
    if kind == "one_hot":
        return (S,)
    if kind == "state_info":
        values = mdp.info.node_values
        return (len(values[0]) + t,) if values else None
    if kind in ("image", "tensor"):
        grid = _grid_shape(mdp)
        if grid is None:
            return None
        rows, cols = grid
        if kind == "image":
            return (rows + t, cols)
        return (rows, cols, len(_SYMBOLS[mdp.info.family]) + t)
    return (n_linear_features(int(np.sum(np.asarray(mdp.state_mask)))),)


def emission_bytes(mdp: MDP, kind: str) -> int:
    """Peak bytes of :func:`emission_table` for ``kind`` (0 when the MDP cannot produce it): per entry of the
    ``[H, S, *obs_shape]`` (continuous ``[S, *obs_shape]``) table, three float64 arrays (the time-free table or its
    time-extended copy, the rows times the state mask, the symbol grids of ``image``/``tensor``), the cast to the
    MDP's dtype and its device copy; the linear kinds' features cover ``H + 1`` steps."""
    shape = emission_shape(mdp, kind)
    if shape is None:
        return 0
    steps = (mdp.H + (1 if kind.startswith("linear") else 0)) if mdp.episodic else 1
    entries = steps * mdp.n_states * math.prod(shape)
    return entries * (24 + 2 * np.dtype(mdp.dtype).itemsize)


def emission_table(mdp: MDP, kind: str, *, key: jax.Array | None = None) -> jax.Array:
    """The observation of every state (and in-episode step) under emission map ``kind`` (module docstring).

    Args:
      mdp: one MDP (not a stacked batch: build a BlockMDP per MDP and stack those).
      kind: one of :data:`EMISSION_KINDS`.
      key: the random key of the linear maps (required for them, ignored otherwise).

    Returns:
      ``[S, *obs_shape]`` (continuous) or ``[H, S, *obs_shape]`` (episodic) in the MDP's dtype; padded states'
      rows are zero.

    Raises:
      ValueError: an unknown kind (closest names listed), a batch of MDPs, a kind the MDP's family cannot produce
        (naming the kinds that work), a linear kind without ``key``.
    """
    kind = check_emission_kind(kind)
    if mdp.T.ndim != 3:
        raise ValueError("emission_table expects a single MDP; build one BlockMDP per MDP and jaxmdp.stack them")
    S = mdp.n_states
    shape = emission_shape(mdp, kind)
    if shape is not None:
        check_memory(
            emission_bytes(mdp, kind),
            f"jaxmdp.emission_table(kind={kind!r})",
            {"S": S, "H": mdp.H, "obs_shape": shape} if mdp.episodic else {"S": S, "obs_shape": shape},
            detail="one observation per state" + (" and step" if mdp.episodic else ""),
            device_bytes=(mdp.H if mdp.episodic else 1) * S * math.prod(shape) * np.dtype(mdp.dtype).itemsize,
            remedy="use a smaller MDP or another emission (one_hot grows with S^2, and with H when episodic), "
            "a narrower dtype, or a machine with more memory",
        )
    table = _state_table(mdp, kind, key)
    if kind in ("linear_optimal", "linear_random"):
        table = table[: mdp.H] if mdp.episodic else table
    else:
        if table.shape[0] < S:  # an MDP padded with jaxmdp.pad: node fields and renderings cover the real states
            table = np.concatenate([table, np.zeros((S - table.shape[0], *table.shape[1:]))])
        if mdp.episodic:
            table = _add_time(table, kind, mdp.H)
    mask = np.asarray(mdp.state_mask).reshape((S,) + (1,) * (table.ndim - 2 if mdp.episodic else table.ndim - 1))
    return jnp.asarray(table * mask, dtype=mdp.dtype)
