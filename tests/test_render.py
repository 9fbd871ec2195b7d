"""Text rendering (docs/families.md §1.10)."""

import pytest

import jaxmdp


def test_river_swim_rendering_and_episodic_header():
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=5, randomize_actions=False)
    assert jaxmdp.render(m, 0) == "A   G"
    assert jaxmdp.render(m, 2) == "S A G"
    assert jaxmdp.render(m, 4, h=3) == "H=3  \n_____\nS   A"


def test_narrow_grids_are_widened_with_x_columns():
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=2, randomize_actions=False)
    assert jaxmdp.render(m, 1, h=12).split("\n") == ["H=12", "____", "SAXX"]


def test_render_rejects_bad_state():
    m = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=3)
    with pytest.raises(ValueError, match="state must be in"):
        jaxmdp.render(m, 7)
