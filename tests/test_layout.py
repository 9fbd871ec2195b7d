"""The layers of the code base, checked on the source (no imports): who may import whom, and no module that changes
process-wide state (matplotlib backend or pyplot state, the recursion limit)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from conftest import REPO

PACKAGES = ("jaxmdp", "agents", "hardness")


def _modules(package: str) -> list[Path]:
    return sorted((REPO / package).rglob("*.py"))


def _imports(path: Path) -> set[str]:
    """Every module name ``path`` imports (absolute imports; the package itself for ``from . import``)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            out.add(node.module)
            out.update(f"{node.module}.{alias.name}" for alias in node.names)
    return out


def _offending(paths: list[Path], forbidden: tuple[str, ...]) -> dict[str, list[str]]:
    bad = {}
    for path in paths:
        hits = sorted(m for m in _imports(path) if m.split(".")[0] in forbidden or m.startswith(forbidden))
        if hits:
            bad[str(path.relative_to(REPO))] = hits
    return bad


def test_jaxmdp_imports_nothing_else_of_ours():
    assert _offending(_modules("jaxmdp"), ("agents", "hardness")) == {}


def test_the_mdp_model_does_not_import_the_experiment_layer():
    shims = {REPO / "jaxmdp" / "runner.py", REPO / "jaxmdp" / "agent_interface.py"}
    core = [p for p in _modules("jaxmdp") if "experiment" not in p.parts and p not in shims]
    assert _offending(core, ("jaxmdp.experiment",)) == {}


def test_agents_import_jaxmdp_only():
    assert _offending(_modules("agents"), ("hardness",)) == {}


def test_hardness_measures_import_jaxmdp_only():
    analyses = ("analysis", "benchmark")
    measures = [p for p in _modules("hardness") if not set(analyses) & set(p.relative_to(REPO / "hardness").parts)]
    assert _offending(measures, ("agents", "hardness.analysis", "hardness.benchmark")) == {}
