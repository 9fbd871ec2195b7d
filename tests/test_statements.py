"""hardness.analysis.statements: the trend read off a curve (against closed forms), the claims, the verdict logic on
synthetic curves, and the outputs of the command (hardness.cli.scenario_statements) on a given measures table."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from hardness.analysis import statements as st

X = np.linspace(0.0, 0.5, 201)


@pytest.mark.parametrize("b", [0.5, 1.0, 2.0, 3.0])
def test_shape_index_of_a_power_is_b_minus_1_over_b_plus_1(b):
    # y = c + x^b on [0, x1]: scaled, y = x^b and k = 2 (1/2 - 1/(b + 1)) = (b - 1) / (b + 1); the trapezoid rule
    # on 201 points is within 1e-3 of it.
    t = st.trend(X, 3.0 + X**b)
    assert t.kind == "increasing"
    assert t.shape_index == pytest.approx((b - 1) / (b + 1), abs=1e-3)
    assert t.shape == {0.5: "sublinear", 1.0: "linear", 2.0: "superlinear", 3.0: "superlinear"}[b]
    assert t.growth == pytest.approx((3.0 + 0.5**b) / 3.0)


def test_trend_kinds():
    # Decreasing: oriented to rise, 1 - x^2 scaled is (x/x1)^2 mirrored; its drop accelerates: k = +1/3.
    t = st.trend(X, 1.0 - X**2)
    assert (t.kind, t.shape) == ("decreasing", "superlinear") and t.shape_index == pytest.approx(1 / 3, abs=1e-3)
    t = st.trend(X, 1.0 - np.sqrt(X))
    assert (t.kind, t.shape) == ("decreasing", "sublinear")
    assert st.trend(X, (X - 0.3) ** 2 + 1).kind == "u_shaped"
    # A dip of less than a tenth of the range before a rise is no U: increasing.
    y = np.concatenate([[1.0, 0.95], np.linspace(1.0, 2.0, 9)])
    assert st.trend(np.arange(11.0), y).kind == "increasing"
    assert st.trend(X, 1.0 + 1e-3 * X).kind == "flat"
    zigzag = np.array([1.0, 3.0, 1.5, 2.5, 1.2, 2.8])
    assert st.trend(np.arange(6.0), zigzag).kind == "other"
    assert st.trend([1.0, 2.0, 4.0], [0.0, 0.0, 0.0]).kind == "flat"
    for x, y, match in (([0, 1], [1, 2], "length >= 3"), ([0, 1, 1], [1, 2, 3], "increase strictly"),
                        ([0, 1, 2], [1, np.inf, 2], "finite")):
        with pytest.raises(ValueError, match=match):
            st.trend(x, y)


def test_claims():
    sup = st.trend(X, X**2)
    assert st.claim_holds("superlinear", sup) and st.claim_holds("increasing", sup)
    assert not st.claim_holds("linear", sup) and not st.claim_holds("decreasing", sup)
    # Almost constant: a range below 10% of the mean, whatever the shape.
    assert st.claim_holds("constant", st.trend(X, 100 + 9 * X / 0.5))
    assert not st.claim_holds("constant", st.trend(X, 100 + 11 * X / 0.5))
    assert st.claim_holds("u_shaped", st.trend(X, (X - 0.2) ** 2))
    with pytest.raises(ValueError, match="claim must be one of"):
        st.claim_holds("grows", sup)


def test_verdicts():
    assert st.verdict(True, True) == "holds in both"
    assert st.verdict(False, True) == "only for the reference's formula"
    assert st.verdict(True, False) == "only for the paper's definition"
    assert st.verdict(False, False) == "in neither"


def _cv(curve):
    """Curves of every (family, setting, scenario, variant) from ``curve(family, setting, scenario, variant)``."""
    out = {}
    for f in st.FAMILIES:
        for s in st.SETTINGS:
            for sc in (1, 2, 3, 4):
                for v in st.VARIANTS:
                    x = X if sc in (1, 2) else np.arange(5.0, 30.0, 5.0)
                    out[(f, s, sc, v)] = (x, {m: curve(f, s, sc, v, m, x) for m in st.MEASURES})
    return out


def test_check_counts_cases_and_applies_the_share():
    statement = st.Statement("k", "App. D", "diameter superlinear", "diameter", (1, 2), "superlinear")
    assert len(statement.cases()) == 18  # 5 families x 2 settings x 2 scenarios, DeepSea without scenario 2
    excluded = st.Statement("k", "x", "t", "diameter", (1, 2), "linear", exclude=(("RiverSwim", "episodic", 2),))
    assert len(excluded.cases()) == 17 and ("RiverSwim", "episodic", 2) not in excluded.cases()

    def curve(f, s, sc, v, m, x):
        # Under "paper", the superlinear claim fails in FrozenLake and SimpleGrid (8 of 18 cases); under "colosseum"
        # only in FrozenLake's continuous scenario 1 (1 of 18).
        fails = f in ("FrozenLake", "SimpleGrid") if v == "paper" else (f, s, sc) == ("FrozenLake", "continuous", 1)
        return 1 + (np.sqrt(x) if fails else x**2)

    (r,) = st.check(_cv(curve), [statement])
    assert r.share("paper") == (10, 18) and r.share("colosseum") == (17, 18)
    assert r.verdict == "only for the reference's formula"
    # Exactly 3/4 of the cases is enough.
    s4 = st.Statement("k", "x", "t", "diameter", (1,), "superlinear", families=("RiverSwim", "SimpleGrid"))
    (r,) = st.check(_cv(lambda f, s, sc, v, m, x: 1 + (x if (f, s) == ("SimpleGrid", "episodic") else x**2)), [s4])
    assert r.share("paper") == (3, 4) and r.verdict == "holds in both"
    missing = st.check({}, [s4])[0]
    assert missing.share("paper") == (0, 0) and missing.verdict == "in neither"


def test_steeper_episodic():
    statement = st.Statement("k", "App. D", "t", "diameter", (1,), "steeper_episodic", families=("RiverSwim",))
    assert statement.cases() == [("RiverSwim", "both", 1)]

    def curve(f, s, sc, v, m, x):
        growth = {"episodic": 10.0, "continuous": 3.0} if v == "paper" else {"episodic": 2.0, "continuous": 3.0}
        return 1 + (growth[s] - 1) * x / x[-1]

    (r,) = st.check(_cv(curve), [statement])
    assert [c.holds for c in r.cases["paper"]] == [True] and [c.holds for c in r.cases["colosseum"]] == [False]
    assert r.cases["paper"][0].reading == "growth x10 episodic vs x3 continuous"


def test_statements_cover_the_paper():
    keys = [s.key for s in st.STATEMENTS]
    assert len(set(keys)) == len(keys)
    for s in st.STATEMENTS:
        assert s.measure in st.MEASURES and s.cases()
        assert set(s.families) <= set(st.FAMILIES)


def test_outputs_from_a_measures_table(tmp_path):
    rows = []
    for f in ("MiniGridEmpty", "RiverSwim"):
        for s in st.SETTINGS:
            for sc in (1, 2, 3, 4):
                for v in st.VARIANTS:
                    values = [0.0, 0.1, 0.2, 0.3] if sc in (1, 2) else [5, 10, 15, 20]
                    for seed in (0, 1):
                        for value in values:
                            x = value if sc in (1, 2) else value / 10
                            row = dict(family=f, setting=s, scenario=sc, variant=v, parameter="p", seed=seed,
                                       value=value, n_states=int(value * 4 + 1) if sc > 2 else 10,
                                       diameter=10 + x**2 + seed, value_norm=(2 - x) if v == "colosseum" else 1 + x,
                                       sum_reciprocal_gaps=100 + x)
                            row.update({f"{m}_converged": True for m in st.MEASURES})
                            rows.append(row)
    path = tmp_path / "out" / "scenario_measures.csv"
    path.parent.mkdir()
    st.write_measures(path, rows)
    back = st.read_measures(path)
    assert back[5]["diameter"] == pytest.approx(rows[5]["diameter"]) and back[5]["diameter_converged"] is True
    from hardness.cli import scenario_statements as cli

    # Every grid of the two families is in the table: nothing is computed for them.
    assert cli.main(["--out", str(path.parent), "--families", "MiniGridEmpty", "RiverSwim", "--quiet",
                     "--no-compile-cache"]) == 0
    md = (path.parent / "statements.md").read_text()
    assert md.count("\n| ") == len(st.STATEMENTS)  # the header is the first line
    # §3.2's value-norm statement: decreasing under "colosseum" only.
    line = next(ln for ln in md.splitlines() if "the value norm decreases as p_lazy" in ln and "§3.2" in ln)
    assert line.endswith("| only for the reference's formula |")
    summary = list(csv.DictReader((path.parent / "statements.csv").open()))
    assert len(summary) == len(st.STATEMENTS)
    assert (path.parent / "statements_episodic.png").stat().st_size > 10_000
