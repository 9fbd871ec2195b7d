"""The paper's statements about how the measures move in its scenarios (§3.2, App. D), checked under both variants.

§3.2 reads the MiniGridEmpty episodic figures and App. D all five families' ("the diameter grows superlinearly with
both p_rand and p_lazy", "the environmental value norm decreases as p_lazy and p_rand increase", ...). Their
figures were made with the reference package's procedures; this module measures every such statement again under
the paper's definitions (``variant="paper"``) and under the reference's (``variant="colosseum"``) on the paper's five
families (:data:`FAMILIES`), both settings, scenarios 1-4 (:mod:`hardness.analysis.scenarios`, measures only, no
agents), and says under which variant it holds.

A *case* is one (family, setting, scenario, variant): the measure's mean over seeds at every grid value, ``y``,
against the grid ``x`` (the swept probability; scenarios 3-4: the mean number of states). :func:`trend` reads the
curve by stated rules:

* ``spearman``: Spearman's rho of ``y`` with ``x`` (scipy), the monotone trend;
* ``rel_range``: ``(max y - min y) / mean |y|``. The paper reads min-max scaled curves (App. E: "only ... trends"),
  so a curve's shape is read whatever its range, unless the range is below :data:`FLAT` (1%: *flat*); the claim
  *almost constant* holds when the range is below :data:`NEAR_CONSTANT` (10%);
* *U-shaped* when the minimum lies inside the grid and both ends lie above it by at least a tenth of the range;
  else *increasing* when ``rho >= MONOTONE`` (0.9), *decreasing* when ``rho <= -MONOTONE``, *other* otherwise;
* ``shape`` of a monotone curve: with ``x`` and ``y`` scaled to ``[0, 1]`` (the figures' min-max scaling) and ``y``
  oriented to rise, twice the area between the chord ``y = x`` and the curve (trapezoid rule),
  ``k = 2 \\int_0^1 (x - y(x)) dx`` in ``[-1, 1]``: ``k > 0`` below the chord (convex: *superlinear*), ``k < 0``
  above it (concave: *sublinear*). ``y = x^b`` gives ``k = (b - 1)/(b + 1)``; ``|k| < LINEAR`` (0.1, i.e.
  ``0.82 < b < 1.22``) reads as *linear*.

A statement (:class:`Statement`) names a measure, the scenarios, families and settings it covers and the trend it
claims (``"superlinear"``, ``"linear"``, ``"sublinear"``, ``"decreasing"``, ``"constant"``, ``"u_shaped"``,
``"steeper_episodic"``); it *holds* under a variant when the claim holds in at least :data:`HOLDS_SHARE` (3/4) of its
cases (a general statement may have a stated exception or two), and the verdict compares the two variants.
"""

from __future__ import annotations

import csv
import dataclasses
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

__all__ = [
    "FAMILIES",
    "SETTINGS",
    "VARIANTS",
    "FLAT",
    "NEAR_CONSTANT",
    "MONOTONE",
    "LINEAR",
    "HOLDS_SHARE",
    "Trend",
    "Statement",
    "STATEMENTS",
    "trend",
    "claim_holds",
    "collect",
    "read_measures",
    "write_measures",
    "curves",
    "CaseResult",
    "StatementResult",
    "check",
    "verdict",
    "markdown_table",
    "statements_figure",
    "write_results",
    "COLUMNS",
]

#: The paper's five families of App. D, in its order.
FAMILIES: tuple[str, ...] = ("MiniGridEmpty", "SimpleGrid", "FrozenLake", "RiverSwim", "DeepSea")
SETTINGS: tuple[str, ...] = ("episodic", "continuous")
VARIANTS: tuple[str, ...] = ("paper", "colosseum")
#: A curve whose relative range is below this is flat (no shape is read).
FLAT = 0.01
#: A curve whose relative range is below this is almost constant (the claim ``"constant"``).
NEAR_CONSTANT = 0.10
#: |Spearman rho| from which a curve is monotone.
MONOTONE = 0.9
#: |shape index| below which a monotone curve is linear.
LINEAR = 0.10
#: Share of its cases in which a statement's claim must hold for the statement to hold.
HOLDS_SHARE = 0.75
MEASURES: tuple[str, ...] = ("diameter", "value_norm", "sum_reciprocal_gaps")


# ---------------------------------------------------------------------------------------------------------------
# Reading one curve
# ---------------------------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Trend:
    """What :func:`trend` reads off one curve (module docstring): ``kind`` one of ``"flat"``,
    ``"increasing"``, ``"decreasing"``, ``"u_shaped"``, ``"other"``; ``shape`` (``"superlinear"``, ``"linear"``,
    ``"sublinear"`` or ``""`` when not monotone); the numbers behind them; ``growth`` ``y[-1] / y[0]``."""

    kind: str
    shape: str
    spearman: float
    rel_range: float
    shape_index: float
    growth: float

    def describe(self) -> str:
        """A short reading, e.g. ``"increasing, superlinear (k=+0.45, range 80%)"``."""
        rng = f"range {100 * self.rel_range:.0f}%"
        if self.kind in ("increasing", "decreasing"):
            return f"{self.kind}, {self.shape} (k={self.shape_index:+.2f}, {rng})"
        if self.kind == "flat":
            return f"flat (range {100 * self.rel_range:.1f}%)"
        return f"{self.kind.replace('_', '-')} (rho={self.spearman:+.2f}, {rng})"


def _spearman(x: np.ndarray, y: np.ndarray) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", stats.ConstantInputWarning)
        return float(stats.spearmanr(x, y)[0])


def trend(x: Sequence[float], y: Sequence[float]) -> Trend:
    """The trend of ``y`` against increasing ``x`` (module docstring for the rules and thresholds).

    Raises:
      ValueError: when ``x`` and ``y`` differ in length, hold fewer than three points, ``x`` does not increase
        strictly or an entry is not finite.
    """
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    if x.shape != y.shape or x.ndim != 1 or x.size < 3:
        raise ValueError(f"x and y must be 1-D of one length >= 3; got shapes {x.shape} and {y.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("x and y must be finite")
    if np.any(np.diff(x) <= 0):
        raise ValueError("x must increase strictly")
    span = float(y.max() - y.min())
    scale = float(np.mean(np.abs(y)))
    rel_range = span / scale if scale > 0 else 0.0
    growth = float(y[-1] / y[0]) if y[0] != 0 else (np.inf if y[-1] > 0 else np.nan)
    if rel_range < FLAT:
        return Trend("flat", "", _spearman(x, y), rel_range, float("nan"), growth)
    rho = _spearman(x, y)
    i = int(np.argmin(y))
    if 0 < i < y.size - 1 and min(y[0], y[-1]) - y[i] >= 0.1 * span:
        return Trend("u_shaped", "", rho, rel_range, float("nan"), growth)
    if abs(rho) >= MONOTONE:
        xs = (x - x[0]) / (x[-1] - x[0])
        ys = (y - y.min()) / span
        if rho < 0:
            ys = 1.0 - ys
        k = float(2.0 * np.trapezoid(xs - ys, xs))
        shape = "linear" if abs(k) < LINEAR else ("superlinear" if k > 0 else "sublinear")
        return Trend("increasing" if rho > 0 else "decreasing", shape, rho, rel_range, k, growth)
    return Trend("other", "", rho, rel_range, float("nan"), growth)


def claim_holds(claim: str, t: Trend) -> bool:
    """Whether trend ``t`` is what ``claim`` says: ``"superlinear"``, ``"linear"`` and ``"sublinear"`` are increasing
    curves of that shape; ``"increasing"``, ``"decreasing"`` and ``"u_shaped"`` are the kinds; ``"constant"``: a
    relative range below :data:`NEAR_CONSTANT`."""
    if claim in ("superlinear", "linear", "sublinear"):
        return t.kind == "increasing" and t.shape == claim
    if claim == "constant":
        return t.rel_range < NEAR_CONSTANT
    if claim in ("increasing", "decreasing", "u_shaped"):
        return t.kind == claim
    raise ValueError(f"claim must be one of superlinear, linear, sublinear, increasing, decreasing, constant, "
                     f"u_shaped; got {claim!r}")


# ---------------------------------------------------------------------------------------------------------------
# The statements
# ---------------------------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Statement:
    """One statement of the paper about how a measure moves (module docstring).

    Attributes:
      key: a short name, e.g. ``"D-diameter-noise"``.
      source: where the paper says it (``"§3.2"`` or ``"App. D"``).
      text: the statement, in the paper's words where short.
      measure: ``"diameter"``, ``"value_norm"`` or ``"sum_reciprocal_gaps"``.
      scenarios: the scenarios it covers.
      claim: the claimed trend (:func:`claim_holds`, or ``"steeper_episodic"``: the growth ``y[-1]/y[0]`` is larger
        in the episodic setting than in the continuous one, one case per family and scenario).
      families, settings: the cases it covers; ``exclude``: ``(family, setting, scenario)`` that the paper names as
        exceptions.
    """

    key: str
    source: str
    text: str
    measure: str
    scenarios: tuple[int, ...]
    claim: str
    families: tuple[str, ...] = FAMILIES
    settings: tuple[str, ...] = SETTINGS
    exclude: tuple[tuple[str, str, int], ...] = ()

    def cases(self) -> list[tuple[str, str, int]]:
        """The ``(family, setting, scenario)`` it covers (DeepSea has no ``p_lazy``, so no scenario 2); for
        ``"steeper_episodic"`` one ``(family, "both", scenario)`` per family and scenario."""
        settings = ("both",) if self.claim == "steeper_episodic" else self.settings
        return [(f, s, sc) for f in self.families for s in settings for sc in self.scenarios
                if not (f == "DeepSea" and sc == 2) and (f, s, sc) not in self.exclude]


_MGE_EP = dict(families=("MiniGridEmpty",), settings=("episodic",))
_FL_MGE_CONT_2 = (("MiniGridEmpty", "continuous", 2), ("FrozenLake", "continuous", 2))
#: The paper's statements about the measures in scenarios 1-4: §3.2 (MiniGridEmpty, episodic) and App. D (all five
#: families, both settings), with the exceptions App. D names.
STATEMENTS: tuple[Statement, ...] = (
    Statement("3.2-diameter-noise", "§3.2", "the diameter grows superlinearly with both p_rand and p_lazy",
              "diameter", (1, 2), "superlinear", **_MGE_EP),
    Statement("3.2-diameter-size", "§3.2", "the diameter increases almost linearly with the number of states; "
              "with p_rand = 0.1 (scenario 4) still approximately linear", "diameter", (3, 4), "linear", **_MGE_EP),
    Statement("3.2-value-norm-noise", "§3.2", "the value norm decreases as p_lazy and p_rand increase",
              "value_norm", (1, 2), "decreasing", **_MGE_EP),
    Statement("3.2-value-norm-size", "§3.2", "the value norm grows sublinearly with the number of states",
              "value_norm", (3, 4), "sublinear", **_MGE_EP),
    Statement("3.2-gaps-noise", "§3.2", "the gap sum increases weakly superlinearly in scenarios 1 and 2",
              "sum_reciprocal_gaps", (1, 2), "superlinear", **_MGE_EP),
    Statement("3.2-gaps-size", "§3.2", "the gap sum increases almost linearly with the number of states",
              "sum_reciprocal_gaps", (3, 4), "linear", **_MGE_EP),
    Statement("D-diameter-noise", "App. D", "the diameter grows superlinearly with both p_rand and p_lazy",
              "diameter", (1, 2), "superlinear"),
    Statement("D-diameter-episodic", "App. D", "the diameter's growth with p_rand and p_lazy is exacerbated in "
              "the episodic setting", "diameter", (1, 2), "steeper_episodic"),
    Statement("D-diameter-size", "App. D", "the diameter increases almost linearly with the number of states "
              "(also with p_rand = 0.1); FrozenLake episodic is the exception", "diameter", (3, 4), "linear",
              exclude=(("FrozenLake", "episodic", 3), ("FrozenLake", "episodic", 4))),
    Statement("D-diameter-size-frozenlake", "App. D", "FrozenLake episodic: more states drastically increase the "
              "visitation complexity", "diameter", (3, 4), "superlinear", families=("FrozenLake",),
              settings=("episodic",)),
    Statement("D-value-norm-noise", "App. D", "the value norm decreases as p_lazy and p_rand increase (except the "
              "two cases below)", "value_norm", (1, 2), "decreasing", exclude=_FL_MGE_CONT_2),
    Statement("D-value-norm-lazy-u", "App. D", "MG-Empty and FrozenLake, continuous: as p_lazy increases the value "
              "norm first decreases and later increases", "value_norm", (2,), "u_shaped",
              families=("MiniGridEmpty", "FrozenLake"), settings=("continuous",)),
    Statement("D-value-norm-size", "App. D", "the value norm grows sublinearly with the number of states",
              "value_norm", (3, 4), "sublinear"),
    Statement("D-gaps-noise", "App. D", "the gap sum increases weakly superlinearly in scenarios 1 and 2 "
              "(FrozenLake excepted)", "sum_reciprocal_gaps", (1, 2), "superlinear",
              families=tuple(f for f in FAMILIES if f != "FrozenLake")),
    Statement("D-gaps-noise-frozenlake", "App. D", "FrozenLake: the gap sum is almost constant in scenarios 1 "
              "and 2", "sum_reciprocal_gaps", (1, 2), "constant", families=("FrozenLake",)),
    Statement("D-gaps-size", "App. D", "the gap sum increases almost linearly with the number of states",
              "sum_reciprocal_gaps", (3, 4), "linear"),
)


# ---------------------------------------------------------------------------------------------------------------
# The measures of every case
# ---------------------------------------------------------------------------------------------------------------

#: Columns of the measures table (:func:`write_measures`).
COLUMNS = ("family", "setting", "scenario", "variant", "parameter", "seed", "value", "n_states", *MEASURES,
           *(f"{m}_converged" for m in MEASURES))
GridKey = tuple[str, str, int, str]


def collect(
    families: Sequence[str] = FAMILIES,
    settings: Sequence[str] = SETTINGS,
    variants: Sequence[str] = VARIANTS,
    scenarios_: Sequence[int] = (1, 2, 3, 4),
    *,
    seeds: Sequence[int] = (0, 1, 2),
    skip: Iterable[GridKey] = (),
    on_grid: Callable[[GridKey, list[dict[str, Any]]], None] | None = None,
) -> list[dict[str, Any]]:
    """The measures of every ``(family, setting, scenario, variant)`` grid (:func:`hardness.analysis.scenarios.
    run_scenario` with its default grids and parameters), one row per ``(seed, value)`` (:data:`COLUMNS`). Grids in
    ``skip`` are not computed; ``on_grid(key, rows)`` is called after each grid (e.g. to save progress)."""
    from hardness.analysis import scenarios

    skip = set(skip)
    out: list[dict[str, Any]] = []
    for family in families:
        for setting in settings:
            for sc in scenarios_:
                if family == "DeepSea" and sc == 2:
                    continue
                for variant in variants:
                    key = (family, setting, sc, variant)
                    if key in skip:
                        continue
                    r = scenarios.run_scenario(sc, family, episodic=setting == "episodic", seeds=tuple(seeds),
                                               variant=variant)
                    rows = []
                    for i, seed in enumerate(r.spec.seeds):
                        for j, value in enumerate(r.spec.values):
                            row = dict(family=family, setting=setting, scenario=sc, variant=variant,
                                       parameter=r.spec.parameter, seed=seed, value=value,
                                       n_states=int(r.n_states[i, j]))
                            row.update({m: float(r.raw[m][i, j]) for m in MEASURES})
                            row.update({f"{m}_converged": bool(r.converged[m][i, j]) for m in MEASURES})
                            rows.append(row)
                    out.extend(rows)
                    if on_grid is not None:
                        on_grid(key, rows)
    return out


def write_measures(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """Write ``rows`` (:func:`collect`) as CSV with :data:`COLUMNS` (atomically: a temporary file, then a rename)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.9g}" if isinstance(r[k], float) else r[k]) for k in COLUMNS})
    tmp.replace(path)


def read_measures(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a table written by :func:`write_measures`, numbers and flags parsed."""
    out = []
    with Path(path).open(newline="") as f:
        for r in csv.DictReader(f):
            row: dict[str, Any] = dict(r)
            row["scenario"], row["seed"], row["n_states"] = int(r["scenario"]), int(r["seed"]), int(r["n_states"])
            row["value"] = float(r["value"])
            for m in MEASURES:
                row[m] = float(r[m])
                row[f"{m}_converged"] = r[f"{m}_converged"] == "True"
            out.append(row)
    return out


def curves(rows: Sequence[Mapping[str, Any]]) -> dict[GridKey, tuple[np.ndarray, dict[str, np.ndarray]]]:
    """Per grid ``(family, setting, scenario, variant)``: ``(x, {measure: y})``, ``y`` the mean over seeds at every
    grid value, ``x`` the swept probability (scenarios 1-2) or the mean number of states over seeds (scenarios 3-4;
    the size parameter where that mean does not increase strictly)."""
    groups: dict[GridKey, list[Mapping[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["family"], r["setting"], int(r["scenario"]), r["variant"]), []).append(r)
    out = {}
    for key, rs in groups.items():
        values = sorted({float(r["value"]) for r in rs})
        at = {v: [r for r in rs if float(r["value"]) == v] for v in values}
        x = np.asarray(values)
        if key[2] in (3, 4):
            n = np.asarray([np.mean([r["n_states"] for r in at[v]]) for v in values])
            if np.all(np.diff(n) > 0):
                x = n
        out[key] = (x, {m: np.asarray([np.mean([r[m] for r in at[v]]) for v in values]) for m in MEASURES})
    return out


# ---------------------------------------------------------------------------------------------------------------
# Checking the statements
# ---------------------------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class CaseResult:
    """One case of a statement under one variant: ``reading`` (e.g. the trend's :meth:`Trend.describe`), whether the
    claim holds, and the trend (``None`` for ``"steeper_episodic"`` and for a case without data)."""

    family: str
    setting: str
    scenario: int
    variant: str
    holds: bool
    reading: str
    trend: Trend | None


@dataclasses.dataclass(frozen=True)
class StatementResult:
    """A statement's cases under both variants and its verdict (:func:`verdict`)."""

    statement: Statement
    cases: Mapping[str, tuple[CaseResult, ...]]
    verdict: str

    def share(self, variant: str) -> tuple[int, int]:
        """``(cases where the claim holds, cases with data)`` under ``variant``."""
        cs = [c for c in self.cases[variant] if c.reading != "no data"]
        return sum(c.holds for c in cs), len(cs)


def _case(statement: Statement, cv: Mapping[GridKey, Any], family: str, setting: str, sc: int,
          variant: str) -> CaseResult:
    if statement.claim == "steeper_episodic":
        growth = {}
        for s in SETTINGS:
            got = cv.get((family, s, sc, variant))
            if got is None:
                return CaseResult(family, setting, sc, variant, False, "no data", None)
            y = got[1][statement.measure]
            growth[s] = float(y[-1] / y[0]) if np.isfinite(y).all() and y[0] > 0 else float("nan")
        holds = bool(growth["episodic"] > growth["continuous"])
        g = {k: "n/a (not finite)" if np.isnan(v) else f"x{v:.3g}" for k, v in growth.items()}
        return CaseResult(family, setting, sc, variant, holds,
                          f"growth {g['episodic']} episodic vs {g['continuous']} continuous", None)
    got = cv.get((family, setting, sc, variant))
    if got is None:
        return CaseResult(family, setting, sc, variant, False, "no data", None)
    x, ys = got
    y = ys[statement.measure]
    fine = np.isfinite(y)
    if fine.sum() < 3:
        return CaseResult(family, setting, sc, variant, False, "not finite", None)
    t = trend(x[fine], y[fine])
    reading = t.describe() + ("" if fine.all() else f" ({int((~fine).sum())} points not finite)")
    return CaseResult(family, setting, sc, variant, claim_holds(statement.claim, t), reading, t)


def verdict(holds_paper: bool, holds_colosseum: bool) -> str:
    """The verdict of a statement from whether it holds under each variant."""
    if holds_paper and holds_colosseum:
        return "holds in both"
    if holds_colosseum:
        return "only for the reference's formula"
    if holds_paper:
        return "only for the paper's definition"
    return "in neither"


def _holds(n_holds: int, n_cases: int) -> bool:
    return n_cases > 0 and n_holds >= HOLDS_SHARE * n_cases


def check(cv: Mapping[GridKey, Any], statements: Sequence[Statement] = STATEMENTS) -> list[StatementResult]:
    """Every statement checked on the curves ``cv`` (:func:`curves`) under both variants (module docstring)."""
    out = []
    for s in statements:
        cases = {v: tuple(_case(s, cv, f, st, sc, v) for f, st, sc in s.cases()) for v in VARIANTS}
        partial = StatementResult(s, cases, "")
        out.append(dataclasses.replace(partial, verdict=verdict(*(_holds(*partial.share(v)) for v in VARIANTS))))
    return out


_SHORT = {"MiniGridEmpty": "MG-Empty", "SimpleGrid": "SimpleGrid", "FrozenLake": "FrozenLake",
          "RiverSwim": "RiverSwim", "DeepSea": "DeepSea"}


def _cell(r: StatementResult, variant: str) -> str:
    cases = r.cases[variant]
    if len(cases) == 1:
        return cases[0].reading
    n, total = r.share(variant)
    fails = [c for c in cases if not c.holds and c.reading != "no data"]
    missing = len(cases) - total
    where = "; ".join(f"{_SHORT.get(c.family, c.family)} {c.setting[:4] + ' ' if c.setting != 'both' else ''}"
                      f"s{c.scenario}: {c.reading}" for c in fails[:4])
    more = f"; +{len(fails) - 4} more" if len(fails) > 4 else ""
    return (f"{n}/{total}" + (f" (not: {where}{more})" if fails else "")
            + (f" ({missing} cases without data)" if missing else ""))


def markdown_table(results: Sequence[StatementResult]) -> str:
    """One row per statement: source, statement, claim, the reading under each variant (a single case's trend, or
    ``holds/cases`` and the cases where it does not hold), the verdict."""
    lines = ["| # | source | statement | claim | `variant=\"paper\"` | `variant=\"colosseum\"` | verdict |",
             "|---|---|---|---|---|---|---|"]
    for k, r in enumerate(results, 1):
        s = r.statement
        claim = s.claim.replace("_", "-")
        lines.append(f"| {k} | {s.source} | {s.text} ({s.measure}, scenarios "
                     f"{', '.join(map(str, s.scenarios))}) | {claim} | {_cell(r, 'paper')} | "
                     f"{_cell(r, 'colosseum')} | {r.verdict} |")
    return "\n".join(lines) + "\n"


def write_results(summary_path: str | Path, cases_path: str | Path, results: Sequence[StatementResult]) -> None:
    """``summary_path``: one row per statement (key, source, measure, scenarios, claim, holds/cases per variant,
    verdict); ``cases_path``: one row per statement, case and variant (the reading and the numbers behind it)."""
    with Path(summary_path).open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["key", "source", "statement", "measure", "scenarios", "claim", "paper_holds", "paper_cases",
                    "colosseum_holds", "colosseum_cases", "verdict"])
        for r in results:
            s = r.statement
            w.writerow([s.key, s.source, s.text, s.measure, " ".join(map(str, s.scenarios)), s.claim,
                        *r.share("paper"), *r.share("colosseum"), r.verdict])
    with Path(cases_path).open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["key", "family", "setting", "scenario", "variant", "holds", "reading", "kind", "shape",
                    "spearman", "rel_range", "shape_index", "growth"])
        for r in results:
            for v in VARIANTS:
                for c in r.cases[v]:
                    t = c.trend
                    nums = ["", "", "", "", "", ""] if t is None else [
                        t.kind, t.shape, f"{t.spearman:.4g}", f"{t.rel_range:.4g}", f"{t.shape_index:.4g}",
                        f"{t.growth:.4g}"]
                    w.writerow([r.statement.key, c.family, c.setting, c.scenario, v, c.holds, c.reading, *nums])


def statements_figure(cv: Mapping[GridKey, Any], setting: str, path: str | Path | None = None) -> Any:
    """The curves behind the statements in one setting: a panel per (measure, scenario), every family's mean curve
    min-max scaled to ``[0, 1]`` (App. E, as the paper's figures), solid under ``variant="paper"``, dashed under
    ``variant="colosseum"``; written to ``path`` when given."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13, 8.2), layout="constrained")
    axes = fig.subplots(len(MEASURES), 4, squeeze=False)
    xlabels = {1: "p_rand", 2: "p_lazy", 3: "number of states", 4: "number of states (p_rand = 0.1)"}
    for i, measure in enumerate(MEASURES):
        for j, sc in enumerate((1, 2, 3, 4)):
            ax = axes[i, j]
            for k, family in enumerate(FAMILIES):
                for variant, style in zip(VARIANTS, ("-", "--")):
                    got = cv.get((family, setting, sc, variant))
                    if got is None:
                        continue
                    x, y = got[0], got[1][measure]
                    fine = np.isfinite(y)
                    if fine.sum() < 2:
                        continue
                    x, y = x[fine], y[fine]
                    xs = (x - x.min()) / (x.max() - x.min()) if sc in (3, 4) else x
                    span = y.max() - y.min()
                    ys = (y - y.min()) / span if span > 1e-12 * max(1.0, abs(y).max()) else np.full_like(y, 0.5)
                    ax.plot(xs, ys, style, color=f"C{k}", lw=1.2,
                            label=f"{_SHORT[family]} ({variant})" if (i, j) == (0, 0) else None)
            if i == 0:
                ax.set_title(f"scenario {sc}", fontsize=9)
            if i == len(MEASURES) - 1:
                ax.set_xlabel(xlabels[sc] + (" (scaled)" if sc in (3, 4) else ""), fontsize=8)
            if j == 0:
                ax.set_ylabel(measure.replace("_", " ") + " (scaled)", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
    fig.legend(loc="outside lower center", ncols=5, fontsize=7)
    fig.suptitle(f"The measures in the scenarios, {setting}: solid variant=\"paper\", dashed variant=\"colosseum\"",
                 fontsize=10)
    if path is not None:
        fig.savefig(path, dpi=100)
    return fig
