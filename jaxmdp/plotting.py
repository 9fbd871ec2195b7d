"""Pictures of an MDP: its graph, a policy's Markov chain, a value function and a run's state-visitation counts; and
a run's regret curves (:func:`draw_regret_curves`).

Every function draws on a given ``matplotlib`` axes, or on a new :class:`matplotlib.figure.Figure` (never pyplot, so
no process-wide state changes), and returns the figure; ``fig.savefig(path)`` writes it. This module imports
matplotlib, so ``import jaxmdp`` does not load it: use ``import jaxmdp.plotting`` (``jaxmdp.plotting`` also works
after ``import jaxmdp``, loaded on first access).

Where the states go (:func:`layout`), from the families' node fields (``MDPInfo.node_fields``):

* grid families (nodes with ``X`` and ``Y``: SimpleGrid, FrozenLake, DeepSea, the MiniGrids, Taxi) on their grid,
  ``Y`` upwards as in the text renderer. A cell holding several states spreads them around its centre: a MiniGrid
  agent's four directions sit towards the side it faces; other extra fields (a key held, a door open, the taxi's
  passenger and destination) on a small circle;
* RiverSwim (``X`` only) on a line, start on the left;
* any other MDP by a spectral layout: the second and third eigenvectors of the Laplacian of the symmetrised kernel
  (Hall 1970, "An r-dimensional quadratic placement algorithm"), falling back to a circle when they collapse states
  onto each other.

Edges are the transitions ``s -> s'`` (self-loops drawn as small rings beside the node), their width growing with the
probability and their colour the expected reward of the transition, ``E[r | s, s']``; probabilities below
:data:`MIN_EDGE_PROBABILITY` are left out. Grid pictures shade the goal cell, walls and holes of the family's layout.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping, Sequence
from typing import Any

import jax
import numpy as np
from matplotlib import colors as mcolors
from matplotlib import cm, colormaps
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, FancyArrowPatch, Rectangle

from jaxmdp.mdp import MDP
from jaxmdp.occupancy import state_distribution
from jaxmdp.values import optimal_policy

__all__ = [
    "MIN_EDGE_PROBABILITY",
    "MEMBER_KEYS",
    "layout",
    "draw_mdp",
    "draw_markov_chain",
    "draw_values",
    "draw_visits",
    "draw_regret_curves",
]

#: Transitions less likely than this are not drawn.
MIN_EDGE_PROBABILITY = 1e-3
#: Above this many edges they are drawn as plain lines (no arrowheads, no curvature), which stays fast.
_MAX_ARROWS = 800
#: Offset of a MiniGrid state from its cell's centre, towards the direction it faces (UP, RIGHT, DOWN, LEFT).
#: (a little to its right, so that the forward moves of opposite directions run on separate lines).
_DIR_OFFSET = np.array([[0.1, 0.27], [0.27, -0.1], [-0.1, -0.27], [-0.27, 0.1]])
_EDGE_CMAP = "coolwarm"


# ---------------------------------------------------------------------------------------------------------------
# Layout
# ---------------------------------------------------------------------------------------------------------------


def layout(mdp: MDP) -> tuple[np.ndarray, str]:
    """Positions ``[S, 2]`` of the states and the kind of layout (``"grid"``, ``"line"`` or ``"spectral"``/
    ``"circle"``), as described in the module docstring."""
    _check_single(mdp)
    info = mdp.info
    fields = tuple(info.node_fields)
    S = mdp.n_states
    if len(info.node_values) == S and "X" in fields:
        nodes = np.asarray(info.node_values, np.float64)
        x = nodes[:, fields.index("X")]
        if "Y" not in fields:
            return np.stack([x, np.zeros_like(x)], axis=1), "line"
        xy = np.stack([x, nodes[:, fields.index("Y")]], axis=1)
        return xy + _cell_offsets(nodes, fields), "grid"
    return _computed_layout(_edge_weights(mdp)[0])


def _cell_offsets(nodes: np.ndarray, fields: tuple[str, ...]) -> np.ndarray:
    """Offsets from the cell centre of the states sharing a cell."""
    extra = [i for i, f in enumerate(fields) if f not in ("X", "Y")]
    if not extra:
        return np.zeros((len(nodes), 2))
    if fields[extra[0]] == "Dir" and len(extra) == 1:
        return _DIR_OFFSET[nodes[:, extra[0]].astype(int) % 4]
    cells: dict[tuple[float, float], list[int]] = {}
    for s, node in enumerate(nodes):
        cells.setdefault((node[fields.index("X")], node[fields.index("Y")]), []).append(s)
    out = np.zeros((len(nodes), 2))
    for members in cells.values():
        if len(members) == 1:
            continue
        order = sorted(members, key=lambda s: tuple(nodes[s, extra]))
        angle = 2 * np.pi * np.arange(len(order)) / len(order) + np.pi / 2
        radius = 0.32 if len(order) > 4 else 0.25
        out[order] = radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    return out


def _computed_layout(W: np.ndarray) -> tuple[np.ndarray, str]:
    S = W.shape[0]
    angle = 2 * np.pi * np.arange(S) / max(S, 1) + np.pi / 2
    circle = np.stack([np.cos(angle), np.sin(angle)], axis=1) * max(1.0, S / (2 * np.pi) * 1.2)
    if S < 4:
        return circle, "circle"
    A = W + W.T
    np.fill_diagonal(A, 0.0)
    lap = np.diag(A.sum(1)) - A
    _, vecs = np.linalg.eigh(lap)
    xy = vecs[:, 1:3]
    xy = (xy - xy.mean(0)) / np.maximum(xy.std(0), 1e-12) * np.sqrt(S) / 2
    d = np.sqrt(((xy[:, None] - xy[None]) ** 2).sum(-1)) + np.eye(S) * 1e9
    if d.min() < 0.15:  # states on top of each other (e.g. a disconnected graph): the circle is readable
        return circle, "circle"
    return xy, "spectral"


# ---------------------------------------------------------------------------------------------------------------
# Public pictures
# ---------------------------------------------------------------------------------------------------------------


def draw_mdp(mdp: MDP, ax: Axes | None = None) -> Figure:
    """The MDP as a graph: an edge ``s -> s'`` where some action moves there, of width growing with the probability
    of getting there under a uniformly random action, ``(1/|A|) sum_a P(s'|s, a)``, coloured by the expected reward of
    the transition, ``sum_a P(s'|s,a) rbar(s,a,s') / sum_a P(s'|s,a)``. Start states (``P0 > 0``) have a thick
    outline. An episodic MDP is drawn as its (time-homogeneous) kernel; the episode restarts from ``P0`` after ``H``
    steps, which is not drawn."""
    _check_single(mdp)
    W, C = _edge_weights(mdp)
    fig, ax = _axes(mdp, ax)
    _draw(ax, mdp, W, C, node_values=None, node_label="", title=_title(mdp, "MDP graph"))
    return fig


def draw_markov_chain(mdp: MDP, policy: Any = None, ax: Axes | None = None) -> Figure:
    """The Markov chain of ``policy`` (default: the optimal policy, :func:`jaxmdp.values.optimal_policy`): edges
    ``P_pi(s'|s) = sum_a pi(a|s) P(s'|s,a)`` coloured by ``E[r | s, s']`` under ``pi``; nodes coloured by the chain's
    state distribution from ``P0`` (:func:`jaxmdp.occupancy.state_distribution`): the stationary distribution of a
    continuous MDP (its long-run distribution from ``P0`` when the chain has several closed classes).

    Episodic MDPs (``policy`` ``[H, S, A]`` or ``[S, A]``): nodes show the average in-episode state distribution
    ``(1/H) sum_h Pr(s_h = s)``, and each edge the transition frequency of an episode,
    ``sum_h Pr(s_h = s) P_{pi_h}(s'|s) / sum_h Pr(s_h = s)`` (states never visited show the time-0 kernel); the
    restart from ``P0`` after ``H`` steps is not drawn."""
    _check_single(mdp)
    T = np.asarray(mdp.T, np.float64)
    if policy is None:
        policy = optimal_policy(mdp)
    pi = np.asarray(policy, np.float64)
    S, A = mdp.n_states, mdp.n_actions
    allowed = [(S, A)] + ([(mdp.H, S, A)] if mdp.episodic else [])
    if pi.shape not in allowed:
        raise ValueError(f"policy must have shape {' or '.join(map(str, allowed))}; got {pi.shape}")
    if mdp.episodic:
        pis = np.broadcast_to(pi, (mdp.H, S, A))
        d_h = [np.asarray(mdp.P0, np.float64)]
        for h in range(mdp.H - 1):
            d_h.append(d_h[-1] @ np.einsum("sa,sat->st", pis[h], T))
        d_h = np.asarray(d_h)
        edge_w = np.einsum("hs,hsa->sa", d_h, pis)  # visit-weighted action frequencies
        seen = d_h.sum(0) > 0
        row_pi = np.where(seen[:, None], edge_w / np.where(seen, d_h.sum(0), 1.0)[:, None], pis[0])
    else:
        row_pi = pi
    P = np.einsum("sa,sat->st", row_pi, T)
    C = _reward_of_edges(mdp, row_pi[:, :, None] * T, P)
    dist = np.asarray(state_distribution(mdp.strip(), jax.numpy.asarray(pi, mdp.dtype)), np.float64)
    fig, ax = _axes(mdp, ax)
    label = "in-episode state distribution" if mdp.episodic else "stationary distribution"
    _draw(ax, mdp, P, C, node_values=dist, node_label=label, title=_title(mdp, "policy's Markov chain"),
          node_cmap="Greens")
    return fig


def draw_values(mdp: MDP, values: Any, ax: Axes | None = None) -> Figure:
    """A value function ``values[S]`` on the MDP's layout (e.g. ``jaxmdp.reference_values(mdp).optimal_state_values``:
    ``V*_0`` of an episodic MDP, the optimal gain from every state of a continuous one), over the grey graph of
    :func:`draw_mdp`."""
    v = _per_state(mdp, values, "values")
    W, _ = _edge_weights(mdp)
    fig, ax = _axes(mdp, ax)
    _draw(ax, mdp, W, None, node_values=v, node_label="value", title=_title(mdp, "values"), node_cmap="viridis")
    return fig


def draw_visits(mdp: MDP, counts: Any, ax: Axes | None = None) -> Figure:
    """State-visitation counts on the MDP's layout (over the grey graph of :func:`draw_mdp`): ``counts[S]``, or
    ``[..., S]`` summed over the leading axes (e.g. the runner's per-member ``RunResult.visits`` of the members that
    ran this MDP). Never-visited states are hollow; the colour scale is logarithmic when counts span over two
    decades."""
    c = np.asarray(counts, np.float64)
    if c.ndim >= 2:
        c = c.reshape(-1, c.shape[-1]).sum(0)
    c = _per_state(mdp, c, "counts")
    if np.any(c < 0):
        raise ValueError("counts must be non-negative")
    W, _ = _edge_weights(mdp)
    fig, ax = _axes(mdp, ax)
    _draw(ax, mdp, W, None, node_values=c, node_label="visits", title=_title(mdp, "state visits"),
          node_cmap="magma_r", log_nodes=c.max() > 100 * max(c[c > 0].min(initial=c.max()), 1.0))
    return fig


# ---------------------------------------------------------------------------------------------------------------
# Runs
# ---------------------------------------------------------------------------------------------------------------

#: What identifies a member of a run: its result's agent, its MDP's label, its hyperparameter set's index and its seed.
MEMBER_KEYS = ("agent", "mdp", "hparams", "seed")


def draw_regret_curves(
    results: Any,
    by: str | Sequence[str] | Callable[[Any, int], Hashable] | None = None,
    *,
    column: str = "cumulative_regret",
    band: str | tuple[float, float] = "sem",
    ax: Axes | None = None,
) -> Figure:
    """Curves of a run's members: ``column`` (a CSV column, :meth:`jaxmdp.experiment.records.RunResult.column`;
    default the cumulative regret) against the steps, one line per group of members, the mean over the group's members
    with a band around it. ``results`` is a :class:`jaxmdp.experiment.records.RunResult` or a sequence of them (e.g.
    one per agent), read through its ``column``, ``steps``, ``grid`` and ``agent`` only (this module does not import
    the experiment layer).

    ``by`` groups the members: names from :data:`MEMBER_KEYS` or fields of the agent's hyperparameters (e.g.
    ``"mdp"``, ``("agent", "mdp")``, ``"learning_rate"``), or a function ``(result, member) -> key``. The default is
    every key of :data:`MEMBER_KEYS` but the seed, so each group is one (agent, MDP, hyperparameter set) over its
    seeds. A line's label names the group by the keys whose values differ between groups (an MDP by its family
    name, ``"RiverSwim"``, when that tells the figure's MDPs apart, else by its full label).

    ``band``: ``"sem"``, the mean ± the standard error of the mean over the group, ``s / sqrt(n)`` with the sample
    standard deviation ``s`` (``ddof = 1``; no band for a group of one member); ``"std"``, the mean ± ``s``; or
    ``(q_lo, q_hi)``, the group's ``q_lo`` and ``q_hi`` quantiles at every record (numpy's linear interpolation), e.g.
    ``(0.25, 0.75)``. The legend's title states which. Groups merged from several results must share their record
    steps.
    """
    runs = [results] if not isinstance(results, (list, tuple)) else list(results)
    if not runs or not all(hasattr(r, "column") and hasattr(r, "grid") for r in runs):
        raise ValueError("results must be a RunResult or a non-empty sequence of RunResults")
    band_name = _band_name(band)
    names, key_of = _member_key(by, runs[0])
    groups: dict[Hashable, list[tuple[int, int]]] = {}
    for i, r in enumerate(runs):
        for b in range(r.grid.n_members):
            groups.setdefault(key_of(r, b), []).append((i, b))
    try:
        cols = [np.asarray(r.column(column), np.float64) for r in runs]
    except KeyError:
        raise ValueError(f"column must be a column of the run's CSV (e.g. 'cumulative_regret'); got {column!r}")
    varying = [k for k in range(len(names)) if len({g[k] for g in groups}) > 1] or list(range(len(names)))
    short = _short_labels({g[k] for g in groups for k in range(len(names)) if names[k] == "mdp"})
    if ax is None:
        fig = Figure(figsize=(6.0, 4.0), layout="constrained")
        ax = fig.add_subplot()
    for key, members in groups.items():
        steps = np.asarray(runs[members[0][0]].steps)
        if any(not np.array_equal(runs[i].steps, steps) for i, _ in members):
            raise ValueError(f"the members of group {key!r} come from results with different record steps; group by "
                             "'agent' (or by a key that separates them)")
        y = np.stack([cols[i][:, b] for i, b in members], axis=1)  # [R, n]
        mean, lo, hi = _band(y, band)
        label = ", ".join(str(key[k]) if names[k] == "agent" else
                          f"mdp={short[key[k]]}" if names[k] == "mdp" else f"{names[k]}={key[k]}" for k in varying)
        (line,) = ax.plot(steps, mean, label=label)
        if lo is not None:
            ax.fill_between(steps, lo, hi, color=line.get_color(), alpha=0.2, linewidth=0)
    ax.set_xlabel("steps")
    ax.set_ylabel(column.replace("_", " "))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, title=f"mean over members; band: {band_name}", title_fontsize=7)
    return ax.figure


def _short_labels(labels: set[str]) -> dict[str, str]:
    """Each MDP label cut at its first ``(`` (``RiverSwim(seed=0,...)`` -> ``RiverSwim``) when the cut labels are
    still distinct, else the labels themselves."""
    cut = {label: label.split("(")[0] for label in labels}
    return cut if len(set(cut.values())) == len(cut) else {label: label for label in labels}


def _band_name(band: Any) -> str:
    if isinstance(band, str) and band in ("sem", "std"):
        return {"sem": "± standard error", "std": "± standard deviation"}[band]
    if (isinstance(band, (tuple, list)) and len(band) == 2 and all(isinstance(q, (int, float)) for q in band)
            and 0.0 <= band[0] < band[1] <= 1.0):
        return f"{band[0]:g}-{band[1]:g} quantiles"
    raise ValueError(f"band must be 'sem', 'std' or a pair of quantile levels 0 <= q_lo < q_hi <= 1; got {band!r}")


def _band(y: np.ndarray, band: Any) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Mean over the members (``y[R, n]``) and the band's lower and upper curves (None for a one-member sem/std)."""
    mean = y.mean(axis=1)
    if isinstance(band, str):
        n = y.shape[1]
        if n < 2:
            return mean, None, None
        half = y.std(axis=1, ddof=1) / (np.sqrt(n) if band == "sem" else 1.0)
        return mean, mean - half, mean + half
    lo, hi = np.quantile(y, [band[0], band[1]], axis=1)
    return mean, lo, hi


def _member_key(by: Any, run: Any) -> tuple[tuple[str, ...], Callable[[Any, int], tuple]]:
    """The key names and the function ``(result, member) -> key tuple`` of ``by``."""
    if callable(by):
        return ("group",), lambda r, b: (by(r, b),)
    if by is None:
        names = tuple(k for k in MEMBER_KEYS if k != "seed")
    else:
        names = (by,) if isinstance(by, str) else tuple(by) if isinstance(by, (list, tuple)) else ()
    if not names or not all(isinstance(n, str) for n in names):
        raise ValueError(f"by must be a key name, a sequence of them or a function (result, member) -> key; got {by!r}")
    for n in names:
        if n not in MEMBER_KEYS and _hparam(run.grid.hparams, n) is None:
            raise ValueError(f"by must name keys of {MEMBER_KEYS} or hyperparameter fields; got {n!r}")

    def one(r: Any, b: int, n: str) -> Hashable:
        g = r.grid
        if n == "agent":
            return r.agent
        if n == "mdp":
            return g.mdp_labels[int(g.mdp_index[b])]
        if n == "hparams":
            return int(g.hparams_index[b])
        if n == "seed":
            return int(g.seeds[b])
        v = _hparam(g.hparams, n)
        if v is None:
            raise ValueError(f"by names the hyperparameter {n!r}, which the agent {r.agent!r} does not have")
        return np.asarray(v)[b].item()

    return names, lambda r, b: tuple(one(r, b, n) for n in names)


def _hparam(hparams: Any, name: str) -> Any:
    """The per-member values ``[B]`` of the hyperparameter ``name`` (None if the agent has no scalar one of that
    name)."""
    v = hparams.get(name) if isinstance(hparams, Mapping) else getattr(hparams, name, None)
    return v if v is not None and np.ndim(v) == 1 else None


# ---------------------------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------------------------


def _check_single(mdp: MDP) -> None:
    if not isinstance(mdp, MDP):
        raise ValueError(f"mdp must be a jaxmdp.MDP; got {type(mdp).__name__}")
    if mdp.T.ndim != 3:
        raise ValueError("the pictures draw one MDP; index a stacked batch with jaxmdp.unstack first")


def _per_state(mdp: MDP, x: Any, name: str) -> np.ndarray:
    _check_single(mdp)
    v = np.asarray(x, np.float64)
    if v.shape != (mdp.n_states,):
        raise ValueError(f"{name} must have shape ({mdp.n_states},), one entry per state; got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be finite")
    return v


def _edge_weights(mdp: MDP) -> tuple[np.ndarray, np.ndarray]:
    """``W[s, s']`` probability under a uniformly random valid action and ``C[s, s']`` expected reward of the edge."""
    T = np.asarray(mdp.T, np.float64)
    mask = np.asarray(mdp.action_mask, np.float64)
    w = T * (mask / mask.sum())[None, :, None]
    W = w.sum(1)
    return W, _reward_of_edges(mdp, w, W)


def _reward_of_edges(mdp: MDP, weighted: np.ndarray, total: np.ndarray) -> np.ndarray:
    """``sum_a weighted[s,a,s'] rbar[s,a,s'] / total[s,s']`` (0 where there is no edge)."""
    rbar = np.asarray(mdp.reward_mean, np.float64)
    num = (weighted * rbar).sum(1)
    return np.where(total > 0, num / np.where(total > 0, total, 1.0), 0.0)


def _title(mdp: MDP, what: str) -> str:
    kind = f"episodic, H={mdp.H}" if mdp.episodic else "continuous"
    return f"{mdp.info.family}: {what} (S={mdp.n_states}, A={mdp.n_actions}, {kind})"


def _axes(mdp: MDP, ax: Axes | None) -> tuple[Figure, Axes]:
    if ax is not None:
        return ax.figure, ax
    xy, kind = layout(mdp)
    span = xy.max(0) - xy.min(0) + 1.0
    if kind == "line":
        size = (max(5.0, 1.3 * span[0]) + 1.5, 3.2)
    else:
        scale = 1.45 if kind == "grid" else 0.9
        w, h = np.clip(span * scale, 3.5, 14.0)
        size = (w + 2.2, h + 0.8)
    fig = Figure(figsize=size, layout="constrained")
    return fig, fig.add_subplot()


def _draw(
    ax: Axes,
    mdp: MDP,
    W: np.ndarray,
    C: np.ndarray | None,
    *,
    node_values: np.ndarray | None,
    node_label: str,
    title: str,
    node_cmap: str = "viridis",
    log_nodes: bool = False,
) -> None:
    xy, kind = layout(mdp)
    real = np.asarray(mdp.state_mask, bool)
    S = mdp.n_states
    if kind == "grid":
        _draw_cells(ax, mdp, xy)
    unit = 1.0 if kind in ("grid", "line") else 0.6
    node_r = (0.085 if S > 40 else 0.14) * unit
    if kind == "grid":  # cells holding many states (a key, a door, a passenger) get smaller nodes
        per_cell = np.unique(np.round(xy), axis=0, return_counts=True)[1].max()
        if per_cell > 4:
            node_r = min(node_r, 0.8 * np.pi * 0.32 / per_cell)
    edge_norm = _edge_norm(C, W)
    cmap = colormaps[_EDGE_CMAP] if C is not None else None
    src, dst = np.nonzero((W >= MIN_EDGE_PROBABILITY) & real[:, None] & real[None, :])
    colour = lambda s, t: cmap(edge_norm(C[s, t])) if C is not None else (0.55, 0.55, 0.55, 0.8)  # noqa: E731
    width = lambda p: 0.3 + (2.4 if S <= 40 else 1.4) * p  # noqa: E731
    loops = src == dst
    for s, t in zip(src[loops], dst[loops]):
        centre = xy[s] + np.array([node_r, node_r]) * 1.1
        ax.add_patch(Circle(centre, node_r * 0.9, fill=False, lw=width(W[s, t]), ec=colour(s, t), zorder=1))
    src, dst = src[~loops], dst[~loops]
    if len(src) > _MAX_ARROWS:
        segs = np.stack([xy[src], xy[dst]], axis=1)
        ax.add_collection(LineCollection(segs, colors=[colour(s, t) for s, t in zip(src, dst)],
                                         linewidths=[width(W[s, t]) for s, t in zip(src, dst)], zorder=1))
    else:
        for s, t in zip(src, dst):
            bend = 0.25 if W[t, s] >= MIN_EDGE_PROBABILITY else 0.1  # a pair of opposite edges bends apart
            gap = (xy[t] - xy[s]) / max(np.linalg.norm(xy[t] - xy[s]), 1e-12) * node_r * 1.15
            ax.add_patch(FancyArrowPatch(
                xy[s] + gap, xy[t] - gap, arrowstyle="-|>", mutation_scale=7 if S > 40 else 10,
                connectionstyle=f"arc3,rad={bend}", lw=width(W[s, t]), color=colour(s, t),
                shrinkA=0, shrinkB=0, zorder=1,
            ))
    if node_values is None:
        face = np.tile(mcolors.to_rgba("white"), (S, 1))
    else:
        norm = _node_norm(node_values, log_nodes)
        face = colormaps[node_cmap](norm(np.maximum(node_values, norm.vmin if log_nodes else -np.inf)))
        if log_nodes or node_label == "visits":
            face[node_values <= 0] = mcolors.to_rgba("white")
        ax.figure.colorbar(cm.ScalarMappable(norm=norm, cmap=node_cmap), ax=ax, label=node_label, shrink=0.8)
    start = np.asarray(mdp.P0) > 0
    for s in np.nonzero(real)[0]:
        ax.add_patch(Circle(xy[s], node_r, fc=face[s], ec="black", lw=2.2 if start[s] else 0.6, zorder=3))
    if S <= 40 and kind != "grid":
        for s in np.nonzero(real)[0]:
            ax.text(*xy[s], str(s), ha="center", va="center", fontsize=8, zorder=4,
                    color="white" if node_values is not None and _dark(face[s]) else "black")
    if C is not None:
        ax.figure.colorbar(cm.ScalarMappable(norm=edge_norm, cmap=_EDGE_CMAP), ax=ax, shrink=0.8,
                           label="expected reward of the transition")
    pad = 0.6 if kind in ("grid", "line") else 0.4 * unit
    ax.set_xlim(xy[real, 0].min() - pad, xy[real, 0].max() + pad)
    ax.set_ylim(xy[real, 1].min() - pad, xy[real, 1].max() + pad)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    start_note = "thick outline: start states" if start.sum() < S else ""
    if kind == "grid":
        fields = mdp.info.node_fields
        note = "each cell: one state per facing direction, placed towards it" if fields == ("X", "Y", "Dir") else ""
        ax.set_xlabel("X\n" + "; ".join(n for n in (note, start_note) if n))
        ax.set_ylabel("Y")
        ax.set_xticks(np.unique(np.round(xy[:, 0])))
        ax.set_yticks(np.unique(np.round(xy[:, 1])))
    elif kind == "line":
        ax.set_xlabel("X" + (f" ({start_note})" if start_note else ""))
        ax.set_yticks([])
    else:
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_xlabel(start_note)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)


def _edge_norm(C: np.ndarray | None, W: np.ndarray) -> mcolors.Normalize:
    if C is None:
        return mcolors.Normalize(0.0, 1.0)
    vals = C[W >= MIN_EDGE_PROBABILITY]
    lo, hi = (float(vals.min()), float(vals.max())) if vals.size else (0.0, 1.0)
    if hi - lo < 1e-9:
        lo, hi = lo - 0.5, hi + 0.5
    return mcolors.Normalize(lo, hi)


def _node_norm(v: np.ndarray, log: bool) -> mcolors.Normalize:
    if log:
        pos = v[v > 0]
        return mcolors.LogNorm(float(pos.min()), float(pos.max()))
    lo, hi = float(v.min()), float(v.max())
    if hi - lo < 1e-12:
        lo, hi = lo - 0.5, hi + 0.5
    return mcolors.Normalize(lo, hi)


def _dark(rgba: Sequence[float]) -> bool:
    r, g, b = rgba[:3]
    return 0.299 * r + 0.587 * g + 0.114 * b < 0.5


def _draw_cells(ax: Axes, mdp: MDP, xy: np.ndarray) -> None:
    """Cell borders, and the goal, walls and holes that the family's layout names."""
    info = mdp.info
    cells = {(int(round(x)), int(round(y))) for x, y in xy}
    for x, y in cells:
        ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, fc="none", ec="0.85", lw=0.8, zorder=0))
    goal = info.layout_value("goal")
    if goal is not None:
        ax.add_patch(Rectangle((goal[0] - 0.5, goal[1] - 0.5), 1, 1, fc="#c8f0c8", ec="none", zorder=0))
        ax.text(goal[0] - 0.45, goal[1] + 0.45, "goal", fontsize=7, va="top", color="darkgreen", zorder=0)
    lake = info.layout_value("lake")
    if lake is not None:
        for x, row in enumerate(lake):
            for y, ch in enumerate(row):
                shade = {"H": "#9ecae1", "G": "#c8f0c8"}.get(ch)
                if shade:
                    ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, fc=shade, ec="none", zorder=0))
    walls = info.layout_value("walls")
    if walls is not None and len(walls) and isinstance(walls[0], tuple) and len(walls[0]) == 2 and \
            not isinstance(walls[0][0], bool):
        for x, y in walls:
            ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, fc="0.6", ec="none", zorder=0))
