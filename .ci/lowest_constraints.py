"""Print pip constraints that pin every direct dependency to the lower bound pyproject.toml declares.

The lowest-versions CI job installs the project with these constraints, so that each ``>=`` bound in
pyproject.toml is a version the suite's smoke subset actually ran on. Read: ``[project].dependencies`` and the extras
named on the command line (default ``test``), following the project's references to its own extras
(``"<project>[deep]"``); a requirement without a ``>=`` bound is left to the resolver.
"""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

PYPROJECT = Path(__file__).resolve().parent.parent / "pyproject.toml"
_REQUIREMENT = re.compile(r"^\s*([A-Za-z0-9_.\-]+)\s*(?:\[([^\]]*)\])?\s*(.*)$")


def lower_bounds(extras: list[str]) -> dict[str, str]:
    """``{distribution: lowest allowed version}`` of the core dependencies and of ``extras``."""
    project = tomllib.loads(PYPROJECT.read_text())["project"]
    own, optional = project["name"].lower(), project.get("optional-dependencies", {})
    bounds: dict[str, str] = {}
    visited: set[str] = set()

    def add(requirements: list[str]) -> None:
        for requirement in requirements:
            match = _REQUIREMENT.match(requirement.split(";")[0])
            if match is None:
                raise SystemExit(f"cannot read requirement {requirement!r}")
            name, nested, spec = match.group(1).lower(), match.group(2), match.group(3)
            if name == own:
                add_extras([e.strip() for e in (nested or "").split(",") if e.strip()])
            elif low := re.search(r">=\s*([0-9][^,\s]*)", spec):
                bounds[name] = low.group(1)

    def add_extras(names: list[str]) -> None:
        for extra in names:
            if extra not in optional:
                raise SystemExit(f"unknown extra {extra!r}; pyproject.toml has {sorted(optional)}")
            if extra not in visited:
                visited.add(extra)
                add(optional[extra])

    add(project["dependencies"])
    add_extras(extras)
    return bounds


if __name__ == "__main__":
    for name, version in sorted(lower_bounds(sys.argv[1:] or ["test"]).items()):
        print(f"{name}=={version}")
