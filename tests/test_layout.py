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


def test_jaxlib_workarounds_import_nothing_of_ours():
    # So that the folder can be deleted as a whole once jaxlib is fixed.
    assert _offending(sorted((REPO / "jaxmdp" / "jaxlib_workarounds").rglob("*.py")), PACKAGES) == {}


def test_agents_import_jaxmdp_only():
    assert _offending(_modules("agents"), ("hardness",)) == {}


def test_hardness_measures_import_jaxmdp_only():
    above = ("analysis", "benchmark", "cli")  # the layers above the measures: analyses, the benchmark, commands
    measures = [p for p in _modules("hardness") if not set(above) & set(p.relative_to(REPO / "hardness").parts)]
    assert _offending(measures, ("agents", "hardness.analysis", "hardness.benchmark", "hardness.cli")) == {}


def test_analyses_and_the_benchmark_do_not_import_the_commands():
    # The command-line layer (hardness/cli) sits on top: argument parsing and printing, then one library call.
    below = [p for p in _modules("hardness") if "cli" not in p.relative_to(REPO / "hardness").parts]
    assert _offending(below, ("hardness.cli",)) == {}


@pytest.mark.parametrize("package", PACKAGES)
def test_no_process_wide_side_effects(package):
    bad = []
    for path in _modules(package):
        tree = ast.parse(path.read_text(), filename=str(path))
        if "matplotlib.pyplot" in _imports(path):
            bad.append(f"{path.name}: imports matplotlib.pyplot")
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
                owner = node.func.value
                name = f"{owner.id}.{node.func.attr}" if isinstance(owner, ast.Name) else node.func.attr
                if name in ("matplotlib.use", "sys.setrecursionlimit"):
                    bad.append(f"{path.name}: calls {name}")
    assert bad == []


def test_short_names_re_export_the_experiment_layer():
    import jaxmdp.agent_interface
    import jaxmdp.experiment.agent_interface
    import jaxmdp.experiment.runner
    import jaxmdp.runner

    for name in jaxmdp.experiment.runner.__all__:
        assert getattr(jaxmdp.runner, name) is getattr(jaxmdp.experiment.runner, name)
    for name in jaxmdp.experiment.agent_interface.__all__:
        assert getattr(jaxmdp.agent_interface, name) is getattr(jaxmdp.experiment.agent_interface, name)

