"""The worked-example notebooks run top to bottom and match their sources.

Each notebook's code cells are read from the ``.ipynb`` JSON and run as one script in a fresh Python process (all
notebooks at once, so the suite pays for the slowest one rather than their sum); any exception fails the test. The
notebooks check their own numbers with ``numpy.testing`` asserts (padding changes no measure, a kernel transform
equals the construction from scratch, the random agent's logged regret is the exact random baseline, a resumed run
equals the uninterrupted one), so running them is a real test, not a smoke test.

The test runs them with smaller run lengths (:data:`SMALL`: every check stays, only fewer steps are simulated; the
build script runs them at full size). Their time is mostly XLA compilation, which does not depend on these sizes.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOK_DIR = ROOT / "notebooks"
NAMES = (
    "01_mdps_and_hardness", "02_agents_and_regret", "03_blockmdps_and_deep_agents", "04_pictures_and_new_measures",
    "05_gymnax_and_ppo", "06_benchmark_your_agent",
)
TIMEOUT_S = 600
#: Source lines replaced before a notebook runs in the test: ``(full size, small)``. Each must occur exactly once, so
#: a notebook edit that renames a parameter fails here instead of silently running at full size. 02's runs are
#: step-bound (12 members x 20 000 steps, twice, plus the resumed run); 2 000 steps still make 20 chunks, so the
#: interruption after 5 chunks and the resume are exercised the same way. 03's three runs (DQN, Q-learning, random,
#: 4 seeds each) keep their checks at 2 000 steps (the random agent's exact baseline, the tabular agent's refusal).
SMALL = {
    "02_agents_and_regret": [("N_STEPS = 20_000\n", "N_STEPS = 2_000\n")],
    "03_blockmdps_and_deep_agents": [("N_STEPS = 20_000\n", "N_STEPS = 2_000\n")],
}


def _load_builder():
    spec = importlib.util.spec_from_file_location("notebook_builder", NOTEBOOK_DIR / "build.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _cells(name: str) -> list[dict]:
    return json.loads((NOTEBOOK_DIR / f"{name}.ipynb").read_text())["cells"]


def _code(name: str) -> str:
    return "\n\n".join("".join(c["source"]) for c in _cells(name) if c["cell_type"] == "code")


def _small_code(name: str) -> str:
    """The notebook's code with the :data:`SMALL` replacements."""
    code = _code(name)
    for full, small in SMALL.get(name, []):
        assert code.count(full) == 1, f"{name}: expected {full!r} exactly once; update SMALL in {__file__}"
        code = code.replace(full, small)
    return code


@pytest.fixture(scope="module")
def launched(request, tmp_path_factory):
    """Start every selected notebook at once, each in its own process and scratch directory; yields
    ``name -> (process, log path)``."""
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    selected = {item.callspec.params["name"] for item in request.session.items
                if getattr(item, "originalname", None) == "test_notebook_runs"}
    procs = {}
    for name in sorted(selected):
        workdir = tmp_path_factory.mktemp(name)
        script = workdir / "notebook.py"
        script.write_text(_small_code(name))
        log = workdir / "output.txt"
        with open(log, "w") as out:
            procs[name] = (
                subprocess.Popen([sys.executable, str(script)], cwd=workdir, env=env, stdout=out,
                                 stderr=subprocess.STDOUT),
                log,
            )
    yield procs
    for proc, _ in procs.values():
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.nightly  # each notebook's steps are tested piecewise in the default profile
@pytest.mark.parametrize("name", NAMES)
def test_notebook_runs(launched, name):
    proc, log = launched[name]
    try:
        proc.wait(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        pytest.fail(f"{name} did not finish within {TIMEOUT_S} s")
    output = log.read_text()
    assert proc.returncode == 0, f"{name} raised:\n{output[-4000:]}"


@pytest.mark.parametrize("name", NAMES)
def test_notebook_matches_its_source_and_was_executed(name):
    builder = _load_builder()
    source = builder.parse_cells((NOTEBOOK_DIR / "src" / f"{name}.py").read_text())
    cells = _cells(name)
    assert [(c["cell_type"], "".join(c["source"])) for c in cells] == source, (
        f"notebooks/{name}.ipynb is stale: run PYTHONPATH=$PWD python scripts/build_notebooks.py {name}"
    )
    code = [c for c in cells if c["cell_type"] == "code"]
    assert [c["execution_count"] for c in code] == list(range(1, len(code) + 1))
    assert not [o for c in code for o in c["outputs"] if o["output_type"] == "error"]
    images = [o for c in code for o in c["outputs"] if "image/png" in o.get("data", {})]
    assert images, f"{name} has no figure output"


def test_parse_cells():
    builder = _load_builder()
    text = '"""docstring, ignored"""\n\n# %% [markdown]\n# # Title\n#\n# text\n\n# %%\nx = 1\n\nx\n\n# %%\n\n'
    assert builder.parse_cells(text) == [("markdown", "# Title\n\ntext"), ("code", "x = 1\n\nx")]
    with pytest.raises(ValueError, match="markdown line"):
        builder.parse_cells("# %% [markdown]\nnot a comment\n")


def test_run_cell_captures_output_and_last_expression():
    builder = _load_builder()
    ns: dict = {}
    outputs = builder.run_cell("print('hi')\ny = 2\ny * 3", ns, 1)
    assert outputs == [
        {"output_type": "stream", "name": "stdout", "text": ["hi\n"]},
        {"output_type": "execute_result", "execution_count": 1, "metadata": {}, "data": {"text/plain": ["6"]}},
    ]
    assert ns["y"] == 2
    with pytest.raises(ZeroDivisionError):
        builder.run_cell("1 / 0", ns, 2)
