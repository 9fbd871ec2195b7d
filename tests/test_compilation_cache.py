"""The scripts' persistent compilation cache and compile-time counters (jaxmdp/experiment/compilation.py).

The cache changes process-wide JAX configuration, so it is exercised in subprocesses, never in the test process.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from jaxmdp.experiment import compilation

ROOT = Path(__file__).resolve().parents[1]

PROBE = """
import json
from jaxmdp.experiment.compilation import setup_compilation
folder, stats = setup_compilation()
import jax, jax.numpy as jnp
jax.jit(lambda x: jnp.sin(x) * 3.0)(jnp.arange(5.0)).block_until_ready()
print(json.dumps({"folder": None if folder is None else str(folder), **stats.snapshot()}))
"""


def _probe(env_value: str) -> dict:
    env = {**os.environ, compilation.CACHE_ENV_VAR: env_value, "PYTHONPATH": str(ROOT)}
    # No wall-clock limit tighter than pytest's own timeout: a slow machine must not fail the test.
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_second_process_hits_the_cache(tmp_path):
    folder = tmp_path / "cache"
    first = _probe(str(folder))
    assert first["folder"] == str(folder)
    assert first["cache_misses"] >= 1 and first["cache_hits"] == 0
    assert any(folder.iterdir())
    second = _probe(str(folder))
    assert second["cache_misses"] == 0 and second["cache_hits"] == first["cache_misses"]
    assert first["compile_s"] > 0 and second["compile_s"] > 0


@pytest.mark.parametrize("value", ["0", "off", "False"])
def test_environment_variable_turns_the_cache_off(value):
    out = _probe(value)
    assert out["folder"] is None and out["cache_hits"] == 0 and out["cache_misses"] == 0


def test_default_folder_is_in_the_user_cache(monkeypatch, tmp_path):
    if sys.platform == "darwin" or os.name == "nt":
        pytest.skip("XDG_CACHE_HOME applies on Linux")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert compilation.default_cache_dir() == tmp_path / "jaxmdp" / "jax_compilation_cache"


def test_nested_compile_spans_count_once():
    stats = compilation.CompileStats()
    trace = "/jax/core/compile/jaxpr_trace_duration"
    stats._on_span(trace, 1.0, 2.0)  # an inner jit traced inside the outer one ...
    stats._on_span(trace, 2.5, 3.0)
    stats._on_span(trace, 0.5, 4.0)  # ... ends before the outer span, which encloses both
    stats._on_span("/jax/core/compile/backend_compile_duration", 4.0, 6.0)
    stats._on_span("/jax/some/other_event", 0.0, 100.0)  # not a compile phase
    stats._on_event("/jax/compilation_cache/cache_hits")
    stats._on_event("/jax/compilation_cache/cache_misses")
    stats._on_event("/jax/compilation_cache/cache_misses")
    assert stats.snapshot() == {
        "compile_s": 5.5, "trace_s": 3.5, "lower_s": 0.0, "backend_s": 2.0, "cache_hits": 1, "cache_misses": 2
    }
    assert compilation.time_report(10.0, stats.snapshot(), None) == (
        "time: 10.0 s, of which compiling 5.5 s (trace 3.5 s, lower 0.0 s, XLA 2.0 s) and running 4.5 s (no cache)"
    )
