"""hardness.analysis.plotting: the percentile bootstrap over seeds against a brute-force numpy bootstrap drawing the
same resamples, NaN handling, and what plot_scenario draws (read back from the figure and the PNG)."""

from __future__ import annotations

import math
import sys

import matplotlib.colors
import matplotlib.image
import numpy as np
import pytest

from hardness.analysis import plotting


def brute_force_means(samples: np.ndarray, n_resamples: int, seed: int) -> np.ndarray:
    """Resample ``b`` draws the seed indices ``idx[b]`` (the documented draw: ``default_rng(seed).integers(0, n,
    (B, n))``); at every grid value, the plain mean of the finite drawn entries, NaN if none."""
    n, V = samples.shape
    idx = np.random.default_rng(seed).integers(0, n, size=(n_resamples, n))
    out = np.empty((n_resamples, V))
    for b in range(n_resamples):
        for j in range(V):
            drawn = [samples[i, j] for i in idx[b] if math.isfinite(samples[i, j])]
            out[b, j] = sum(drawn) / len(drawn) if drawn else math.nan
    return out


def linear_quantile(values: list[float], q: float) -> float:
    """The ``q`` quantile with linear interpolation between order statistics (numpy's default), by hand."""
    v = sorted(values)
    pos = q * (len(v) - 1)
    lo = math.floor(pos)
    hi = min(lo + 1, len(v) - 1)
    return v[lo] + (pos - lo) * (v[hi] - v[lo])


def brute_force_ci(samples: np.ndarray, level: float, n_resamples: int, seed: int):
    means = brute_force_means(samples, n_resamples, seed)
    alpha = (1.0 - level) / 2.0
    n, V = samples.shape
    mean, lo, hi = np.full(V, np.nan), np.full(V, np.nan), np.full(V, np.nan)
    for j in range(V):
        col = [x for x in samples[:, j] if math.isfinite(x)]
        if col:
            mean[j] = sum(col) / len(col)
        boot = [m for m in means[:, j] if math.isfinite(m)]
        if boot:
            lo[j], hi[j] = linear_quantile(boot, alpha), linear_quantile(boot, 1.0 - alpha)
    return mean, lo, hi


@pytest.fixture
def samples():
    """5 seeds x 4 values with an infinite entry, a NaN, and a column with one finite seed only."""
    x = np.random.default_rng(3).normal(size=(5, 4))
    x[1, 0] = np.inf
    x[3, 2] = np.nan
    x[[0, 1, 2, 4], 3] = np.nan  # only seed 3 is finite at value 3: some resamples miss it
    return x


def test_bootstrap_means_equals_brute_force(samples):
    got = plotting.bootstrap_means(samples, n_resamples=300, seed=7)
    want = brute_force_means(samples, 300, 7)
    assert got.shape == (300, 4)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    # Resamples that draw seed 3 at least once have its value at column 3; the others are NaN.
    col = got[:, 3]
    assert np.isnan(col).any() and np.isfinite(col).any()
    np.testing.assert_array_equal(col[np.isfinite(col)], samples[3, 3])


def test_bootstrap_means_seed_is_the_only_randomness(samples):
    a = plotting.bootstrap_means(samples, 50, seed=1)
    np.testing.assert_array_equal(a, plotting.bootstrap_means(samples, 50, seed=1))
    assert not np.allclose(a[:, 1], plotting.bootstrap_means(samples, 50, seed=2)[:, 1])


@pytest.mark.parametrize("level", [0.95, 0.8])
def test_bootstrap_ci_equals_brute_force(samples, level):
    mean, lo, hi = plotting.bootstrap_ci(samples, level=level, n_resamples=400, seed=11)
    w_mean, w_lo, w_hi = brute_force_ci(samples, level, 400, 11)
    for got, want in ((mean, w_mean), (lo, w_lo), (hi, w_hi)):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    # The mean leaves out the infinite and the NaN entries.
    assert mean[0] == pytest.approx(np.mean(samples[[0, 2, 3, 4], 0]), rel=1e-12)
    assert mean[2] == pytest.approx(np.mean(samples[[0, 1, 2, 4], 2]), rel=1e-12)
    assert mean[3] == lo[3] == hi[3] == samples[3, 3]
    assert np.all(lo <= mean + 1e-12) and np.all(mean <= hi + 1e-12)


def test_bootstrap_ci_degenerate_columns():
    x = np.array([[1.0, 2.0, np.nan, np.inf], [1.0, 4.0, np.nan, np.nan], [1.0, 6.0, np.nan, -np.inf]])
    mean, lo, hi = plotting.bootstrap_ci(x, n_resamples=200, seed=0)
    np.testing.assert_array_equal(mean[:2], [1.0, 4.0])
    assert lo[0] == hi[0] == 1.0  # constant column: no spread
    assert 2.0 <= lo[1] < 4.0 < hi[1] <= 6.0
    assert np.isnan(mean[2:]).all() and np.isnan(lo[2:]).all() and np.isnan(hi[2:]).all()
    # One seed: every resample is that seed.
    mean, lo, hi = plotting.bootstrap_ci(np.array([[0.3, 0.7]]), n_resamples=20)
    np.testing.assert_array_equal(mean, [0.3, 0.7])
    np.testing.assert_array_equal(lo, [0.3, 0.7])
    np.testing.assert_array_equal(hi, [0.3, 0.7])


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: plotting.bootstrap_means(np.zeros(3)), "samples"),
        (lambda: plotting.bootstrap_means(np.zeros((0, 3))), "samples"),
        (lambda: plotting.bootstrap_means(np.zeros((2, 0))), "samples"),
        (lambda: plotting.bootstrap_means(np.zeros((2, 3)), n_resamples=0), "n_resamples"),
        (lambda: plotting.bootstrap_means(np.zeros((2, 3)), n_resamples=True), "n_resamples"),
        (lambda: plotting.bootstrap_means(np.zeros((2, 3)), n_resamples=10.0), "n_resamples"),
        (lambda: plotting.bootstrap_ci(np.zeros((2, 3)), level=1.0), "level"),
        (lambda: plotting.bootstrap_ci(np.zeros((2, 3)), level=0.0), "level"),
        (lambda: plotting.bootstrap_ci(np.zeros((2, 3)), level="0.9"), "level"),
    ],
)
def test_bootstrap_errors_name_the_parameter(call, name):
    with pytest.raises(ValueError, match=name):
        call()


# ---------------------------------------------------------------------------------------------------------------
# plot_scenario
# ---------------------------------------------------------------------------------------------------------------


@pytest.fixture
def drawn(monkeypatch):
    """The figures plot_scenario draws, kept for inspection."""
    figs = []
    build = plotting.scenario_figure

    def keep(*args, **kwargs):
        figs.append(build(*args, **kwargs))
        return figs[-1]

    monkeypatch.setattr(plotting, "scenario_figure", keep)
    return figs


def no_pyplot_figures() -> bool:
    """Plotting leaves pyplot's global state alone: no open pyplot figure (if pyplot is loaded at all)."""
    plt = sys.modules.get("matplotlib.pyplot")
    return plt is None or plt.get_fignums() == []


def test_plot_scenario_draws_a_line_and_a_band_per_curve(tmp_path, drawn):
    x = np.array([0.0, 0.1, 0.2, 0.3])
    rng = np.random.default_rng(0)
    curves = {
        "diameter": rng.uniform(size=(4, 4)),
        "value_norm": rng.uniform(size=(4, 4)),
        "regret": rng.uniform(size=(4, 4)),  # an unknown key is labelled by itself
    }
    curves["value_norm"][:, 2] = np.nan  # no finite seed at x = 0.2: the point is left out
    path = plotting.plot_scenario(x, curves, tmp_path / "sub" / "fig.png", xlabel="p_rand", title="T",
                                  n_resamples=100, seed=3)
    assert path == tmp_path / "sub" / "fig.png" and path.exists()
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = matplotlib.image.imread(path)
    assert img.shape == (540, 750, 4) and img[..., :3].std() > 0.05

    (fig,) = drawn
    (ax,) = fig.axes
    assert len(ax.lines) == 3 and len(ax.collections) == 3
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["Diameter", "Environmental value norm", "regret"]
    assert ax.get_xlabel() == plotting.AXIS_LABELS["p_rand"] and ax.get_title() == "T"
    for line, band, values in zip(ax.lines, ax.collections, curves.values()):
        mean, lo, hi = brute_force_ci(values, 0.95, 100, 3)
        ok = np.isfinite(mean)
        np.testing.assert_allclose(line.get_xdata(), x[ok])
        np.testing.assert_allclose(line.get_ydata(), mean[ok], rtol=1e-12)
        verts = np.concatenate([p.vertices for p in band.get_paths()])
        # The band's outline runs through (x, lo) and (x, hi) at every plotted point, and nowhere else.
        for xv, l, h in zip(x[ok], lo[ok], hi[ok]):
            at = verts[np.isclose(verts[:, 0], xv)][:, 1]
            assert np.isclose(at, l).any() and np.isclose(at, h).any()
        assert np.isclose(verts[:, 1].min(), lo[ok].min()) and np.isclose(verts[:, 1].max(), hi[ok].max())
        assert np.allclose(band.get_facecolor()[0][:3], matplotlib.colors.to_rgb(line.get_color()))
    assert len(ax.lines[1].get_xdata()) == 3
    assert no_pyplot_figures()


def test_plot_scenario_free_text_axis_label(tmp_path, drawn):
    plotting.plot_scenario([4, 9, 16], {"diameter": np.ones((2, 3))}, tmp_path / "f.png", xlabel="States (mean)")
    assert drawn[0].axes[0].get_xlabel() == "States (mean)"
    assert plotting.AXIS_LABELS["n_states"] == "Number of states"


@pytest.mark.parametrize(
    "x, curves, name",
    [
        (np.zeros((2, 2)), {"diameter": np.zeros((1, 2))}, "x"),
        (np.zeros(2), {}, "curves"),
        (np.zeros(2), {"diameter": np.zeros((1, 3))}, "curves['diameter']"),
        (np.zeros(2), {"diameter": np.zeros(2)}, "curves['diameter']"),
    ],
)
def test_plot_scenario_errors(tmp_path, x, curves, name):
    with pytest.raises(ValueError) as err:
        plotting.plot_scenario(x, curves, tmp_path / "f.png", xlabel="p_rand")
    assert name in str(err.value)
    assert no_pyplot_figures()
    assert not (tmp_path / "f.png").exists()
