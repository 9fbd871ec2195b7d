"""jaxmdp.plotting: every picture renders to a PNG of sensible size for the families' layouts and a custom MDP, the
layouts put states where the families say, and bad input is refused."""

from __future__ import annotations

import jax
import matplotlib.image
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.patches import Circle, FancyArrowPatch
from matplotlib.path import Path

import jaxmdp
import jaxmdp.plotting as plotting

from conftest import random_mdp


def _png(fig: Figure, path) -> np.ndarray:
    fig.savefig(path, dpi=60)
    assert path.stat().st_size > 5_000  # an empty figure is ~2 kB
    img = matplotlib.image.imread(path)
    assert 150 < img.shape[0] < 1500 and 250 < img.shape[1] < 1500
    return img


@jax.jit
def _optimal_values(m):
    return jaxmdp.reference_values(m).optimal_state_values


@pytest.fixture(scope="module")
def mdps():
    rng = np.random.default_rng(0)
    return {
        "minigrid": jaxmdp.make("MiniGridEmpty", episodic=False, seed=0, size=5),
        "river": jaxmdp.make("RiverSwim", episodic=False, seed=0, size=6, p_rand=0.1),
        "deepsea": jaxmdp.make("DeepSea", episodic=True, seed=0, size=5),
        "custom": random_mdp(rng, S=7, A=2),
    }


@pytest.mark.parametrize("name", ["minigrid", "river", "deepsea", "custom"])
def test_every_picture_renders(mdps, name, tmp_path):
    m = mdps[name]
    S = m.n_states
    figs = {
        "mdp": plotting.draw_mdp(m),
        "chain": plotting.draw_markov_chain(m),
        "values": plotting.draw_values(m, np.asarray(_optimal_values(m.strip()))),
        "visits": plotting.draw_visits(m, np.arange(2 * S).reshape(2, S)),
    }
    for what, fig in figs.items():
        assert isinstance(fig, Figure)
        img = _png(fig, tmp_path / f"{name}_{what}.png")
        assert img[..., :3].std() > 0.05  # something is drawn


def test_given_axes_are_used(mdps, tmp_path):
    fig = Figure(figsize=(10, 4))
    axes = fig.subplots(1, 2)
    assert plotting.draw_mdp(mdps["river"], ax=axes[0]) is fig
    assert plotting.draw_markov_chain(mdps["river"], ax=axes[1]) is fig
    assert len(axes[0].patches) > mdps["river"].n_states  # nodes and edges
    _png(fig, tmp_path / "two.png")


def test_layouts(mdps):
    xy, kind = plotting.layout(mdps["river"])
    assert kind == "line"
    np.testing.assert_array_equal(xy[:, 0], [v[0] for v in mdps["river"].info.node_values])
    xy, kind = plotting.layout(mdps["minigrid"])
    assert kind == "grid"
    nodes = np.asarray(mdps["minigrid"].info.node_values)
    np.testing.assert_array_equal(np.round(xy), nodes[:, :2])  # every state inside its own cell
    assert len({tuple(p) for p in np.round(xy, 6)}) == len(xy)  # no two states on top of each other
    up, right = (nodes[:, 2] == 0), (nodes[:, 2] == 1)
    assert np.all(xy[up, 1] > nodes[up, 1]) and np.all(xy[right, 0] > nodes[right, 0])
    xy, kind = plotting.layout(mdps["custom"])
    assert kind in ("spectral", "circle") and xy.shape == (7, 2)


def drawn_graph(ax) -> tuple[set[tuple[int, int]], np.ndarray]:
    """The graph a picture shows, read back from its patches: the edges ``(s, t)`` (an arrow from the node nearest its
    start to the other node nearest its path; a ring for a self-loop, at the node nearest its centre) and the nodes'
    face colours ``[S, 4]`` (filled circles, in state order when the layout puts state ``s`` at ``x = s``)."""
    nodes = [p for p in ax.patches if isinstance(p, Circle) and p.get_fill()]
    centres = np.array([p.center for p in nodes])
    order = np.argsort(centres[:, 0])
    centres = centres[order]
    nearest = lambda xy: int(np.argmin(np.linalg.norm(centres - np.asarray(xy), axis=-1)))  # noqa: E731
    edges = set()
    for p in ax.patches:
        if isinstance(p, Circle) and not p.get_fill():
            s = nearest(p.center)
            edges.add((s, s))
        elif isinstance(p, FancyArrowPatch):
            path = p.get_path()
            v = path.vertices[path.codes != Path.CLOSEPOLY] if path.codes is not None else path.vertices
            s = nearest(v[0])
            d = np.linalg.norm(v[:, None, :] - centres[None], axis=-1).min(axis=0)
            d[s] = np.inf
            edges.add((s, int(np.argmin(d))))
    return edges, np.array([nodes[i].get_facecolor() for i in order])


def test_chain_draws_the_policy_edges_and_its_stationary_distribution():
    # Deterministic RiverSwim 6 with action 0 = left, action 1 = right in every state (checked on T below). The
    # chain of "always right" has the edges s -> s + 1 and the loop at 5, and all its stationary mass on state 5;
    # "always left" the edges s -> s - 1, the loop at 0 and its mass on state 0; the MDP graph has both sets. The
    # pictures are read back edge by edge and node by node, so exchanging the actions (or drawing the MDP's edges,
    # or another policy's) fails.
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=6, randomize_actions=False)
    S = m.n_states
    T = np.asarray(m.T)
    np.testing.assert_array_equal(T[np.arange(S), 1].argmax(-1), np.minimum(np.arange(S) + 1, S - 1))
    np.testing.assert_array_equal(T[np.arange(S), 0].argmax(-1), np.maximum(np.arange(S) - 1, 0))
    right_edges = {(s, min(s + 1, S - 1)) for s in range(S)}
    left_edges = {(s, max(s - 1, 0)) for s in range(S)}
    for action, edges, mass_on in ((1, right_edges, S - 1), (0, left_edges, 0)):
        policy = np.zeros((S, m.n_actions))
        policy[:, action] = 1.0
        drawn, faces = drawn_graph(plotting.draw_markov_chain(m, policy).axes[0])
        assert drawn == edges, f"always action {action}"
        darkness = 1.0 - faces[:, :3].mean(-1)  # the Greens map darkens with the probability
        others = np.delete(darkness, mass_on)
        assert darkness[mass_on] > others.max() + 0.5 and np.ptp(others) == 0.0, f"always action {action}: {darkness}"
    drawn, _ = drawn_graph(plotting.draw_mdp(m).axes[0])
    assert drawn == right_edges | left_edges


def test_bad_input(mdps):
    m = mdps["river"]
    with pytest.raises(ValueError, match="values"):
        plotting.draw_values(m, np.zeros(3))
    with pytest.raises(ValueError, match="counts"):
        plotting.draw_visits(m, -np.ones(m.n_states))
    with pytest.raises(ValueError, match="policy"):
        plotting.draw_markov_chain(m, np.ones((2, 2)))
    with pytest.raises(ValueError, match="unstack"):
        plotting.draw_mdp(jaxmdp.stack([m, m]))


def test_plotting_is_lazy():
    import subprocess
    import sys

    code = "import sys, jaxmdp; assert 'matplotlib' not in sys.modules; jaxmdp.plotting.draw_mdp; print('ok')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "ok", out.stderr
