"""Load another version of one of the package's modules beside the current one, for same-process before/after
benchmarks (``scripts/bench_gain_vector.py``, ``scripts/bench_psrl_structured_plan.py``): from a file, or from a git
revision of this checkout."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import tempfile
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


def load_file(path: str | Path, name: str) -> ModuleType:
    """The module in ``path``, imported under ``name`` (registered in ``sys.modules``: dataclasses look it up)."""
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def load_revision(revision: str, relpath: str, name: str) -> ModuleType:
    """``relpath`` (e.g. ``jaxmdp/dynamic_programming.py``) as it is at git ``revision``, imported under ``name``."""
    source = subprocess.run(["git", "show", f"{revision}:{relpath}"], cwd=ROOT, check=True, capture_output=True,
                            text=True).stdout
    path = Path(tempfile.mkdtemp()) / f"{name}.py"
    path.write_text(source)
    return load_file(path, name)
