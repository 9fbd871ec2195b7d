"""Text rendering of states (docs/families.md §1.10; paper App. C textual representations).

Each family registers a function ``(info, node) -> list[list[str]]`` returning a character grid for the node (a tuple
of the family's node fields) using the family's symbols; :func:`render` adds the episodic header: a first row
``H=<h>`` left-aligned and padded with spaces, a second row of ``_``, the grid being first widened on the right with
columns of ``X`` when it has fewer than ``2 + len(str(h))`` columns.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from jaxmdp.mdp import MDP, MDPInfo

__all__ = ["render", "render_grid", "register_renderer"]

Renderer = Callable[[MDPInfo, tuple[int, ...]], list[list[str]]]
_RENDERERS: dict[str, Renderer] = {}


def register_renderer(family: str, renderer: Renderer) -> None:
    """Register the grid renderer of ``family``."""
    _RENDERERS[family] = renderer


def render_grid(mdp: MDP, state: int, h: int | None = None) -> list[list[str]]:
    """The character grid of ``state`` (an index), with the episodic header when ``h`` is given."""
    info = mdp.info
    if mdp.T.ndim != 3:
        raise ValueError("render expects a single MDP; index a stacked batch with jaxmdp.unstack first")
    if info.family not in _RENDERERS:
        raise ValueError(f"no text renderer for family {info.family!r}")
    state = int(np.asarray(state))
    if not 0 <= state < len(info.node_values):
        raise ValueError(f"state must be in [0, {len(info.node_values)}); got {state}")
    grid = [list(row) for row in _RENDERERS[info.family](info, info.node_values[state])]
    if h is None:
        return grid
    label = f"H={int(h)}"
    width = len(grid[0])
    if width < 2 + len(str(int(h))):
        extra = 2 + len(str(int(h))) - width
        grid = [row + ["X"] * extra for row in grid]
        width = len(grid[0])
    return [list(label.ljust(width)), ["_"] * width, *grid]


def render(mdp: MDP, state: int, h: int | None = None) -> str:
    """Text rendering of ``state`` (rows joined by newlines); pass ``h`` for the episodic header."""
    return "\n".join("".join(row) for row in render_grid(mdp, state, h))
