"""Shared test helpers: small random MDPs and access to the reference data in ``../shared`` (optional)."""

from __future__ import annotations

import gc
import json
import logging
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

import jax

import jaxmdp

REPO = Path(__file__).resolve().parents[1]


def shared_dir() -> Path | None:
    """``$JAXMDP_SHARED`` or ``../shared`` next to the repository, if present."""
    env = os.environ.get("JAXMDP_SHARED")
    for cand in ([Path(env)] if env else []) + [REPO.parent / "shared", REPO / "shared"]:
        if (cand / "reference" / "colosseum" / "index.json").exists():
            return cand
    return None


def missing_reference_error(environ: dict, shared: Path | None) -> str | None:
    """Why the suite must not run: in CI (``CI=true``) the reference data is required, so that the parity tests
    cannot turn themselves into skips; ``None`` when it may run."""
    if shared is None and environ.get("CI", "").lower() == "true":
        return ("CI=true but the reference data is missing: the parity tests need ../shared/reference/colosseum "
                "(or $JAXMDP_SHARED pointing to a folder holding reference/colosseum/index.json)")
    return None


#: The session's compilation-cache folder: its key in an xdist worker's input, and the controller's stash key.
_CACHE_KEY = "jaxmdp_test_compilation_cache"
_STASH = pytest.StashKey[str]()


#: Parameter sets of the longest parametrisations that the default profile leaves to the nightly one
#: (.ci/nightly_params.py writes it; docs/testing.md, "Profiles"). ``JAXMDP_NIGHTLY_PARAMS=off`` ignores it.
NIGHTLY_PARAMS = Path(__file__).parent / "nightly_params.txt"


@pytest.hookimpl(tryfirst=True)  # before -m deselects by marker
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the parameter sets listed in :data:`NIGHTLY_PARAMS` nightly."""
    if os.environ.get("JAXMDP_NIGHTLY_PARAMS") == "off" or not NIGHTLY_PARAMS.exists():
        return
    listed = {line.strip() for line in NIGHTLY_PARAMS.read_text().splitlines()
              if line.strip() and not line.startswith("#")}
    for item in items:
        if item.nodeid in listed:
            item.add_marker(pytest.mark.nightly)


def pytest_configure(config: pytest.Config) -> None:
    """One persistent JAX compilation cache for the session, in a fresh temporary folder shared by the xdist workers: a
    program that another test (or the other worker) already compiled with the same HLO is loaded instead of compiled
    again (the runner's programs recur across modules, and :func:`_release_compiled_programs` may drop the in-memory
    ones). Measured on six of the slowest modules, 2 workers: 386 -> 330 s (the whole suite: 1 662 -> 1 635 s, within
    run-to-run noise). It starts empty, so results cannot depend on an earlier run; subprocesses the tests start do not
    inherit it."""
    workerinput = getattr(config, "workerinput", None)
    if workerinput is None:
        folder = tempfile.mkdtemp(prefix="jaxmdp-test-compilation-cache-")
        config.stash[_STASH] = folder
    else:
        folder = workerinput[_CACHE_KEY]
    jax.config.update("jax_compilation_cache_dir", folder)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node) -> None:
    """Hand the controller's cache folder to an xdist worker (pytest-xdist hook)."""
    node.workerinput[_CACHE_KEY] = node.config.stash[_STASH]


def pytest_unconfigure(config: pytest.Config) -> None:
    folder = config.stash.get(_STASH, None)
    if folder is not None:
        shutil.rmtree(folder, ignore_errors=True)


def pytest_sessionstart(session: pytest.Session) -> None:
    shared = shared_dir()
    error = missing_reference_error(dict(os.environ), shared)
    if error is not None:
        pytest.exit(error, returncode=1)
    if shared is None:
        print("note: ../shared/reference is absent; the parity tests are skipped (in CI this is an error)")


def reference_index() -> list[dict]:
    """Entries of ``reference/colosseum/index.json`` (empty when the shared folder is absent)."""
    root = shared_dir()
    if root is None:
        return []
    return json.loads((root / "reference" / "colosseum" / "index.json").read_text())["files"]


def load_reference(entry: dict) -> dict:
    root = shared_dir()
    with np.load(root / "reference" / "colosseum" / entry["file"]) as z:
        return {k: z[k] for k in z.files}


def build_reference_mdp(entry: dict) -> jaxmdp.MDP:
    """Build the MDP of a reference entry with jaxmdp."""
    params = dict(entry["constructor_params"])
    seed = params.pop("seed")
    return jaxmdp.make(entry["family"], episodic=entry["setting"] == "episodic", seed=seed, **params)


def reference_params(every: bool = True):
    """``pytest.param`` per reference entry, or one skipped param when ``../shared`` is absent. ``every=False``: the
    default profile runs the first entry of each family and setting, the others are nightly (docs/testing.md,
    "Profiles")."""
    entries = reference_index()
    if not entries:
        return [pytest.param(None, marks=pytest.mark.skip(reason="../shared/reference is not available"))]
    seen: set[tuple[str, str]] = set()
    params = []
    for e in entries:
        first = (e["family"], e["setting"]) not in seen
        seen.add((e["family"], e["setting"]))
        params.append(pytest.param(e, id=e["id"], marks=() if every or first else pytest.mark.nightly))
    return params


def nightly_beyond(params, keep, ids=None) -> list:
    """``params`` (values, tuples of values or ``pytest.param``) with every set for which ``keep(values)`` is false
    marked nightly: the default profile runs a representative share of a long parametrisation, the nightly profile
    all of it (docs/testing.md, "Profiles"). ``ids(values)`` names a set (default: pytest's)."""
    out = []
    for p in params:
        if not hasattr(p, "values"):
            p = pytest.param(*(p if isinstance(p, tuple) else (p,)))
        values = p.values if len(p.values) > 1 else p.values[0]
        marks = list(p.marks) + ([] if keep(values) else [pytest.mark.nightly])
        out.append(pytest.param(*p.values, id=p.id if ids is None else ids(values), marks=marks))
    return out


def compilations(caplog: pytest.LogCaptureFixture, calls) -> list[str]:
    """The XLA compilations logged while the zero-argument ``calls`` run (eagerly, in order; results waited for)."""
    caplog.clear()
    with jax.log_compiles(True), caplog.at_level(logging.WARNING):
        for call in calls:
            jax.block_until_ready(call())
    return [r.getMessage() for r in caplog.records if "Compiling" in r.getMessage()]


def random_mdp(
    rng: np.random.Generator, S: int = 6, A: int = 3, H: int | None = None, sparsity: float = 0.5
) -> jaxmdp.MDP:
    """A random MDP with sparse random kernels, Beta and point-mass rewards."""
    T = rng.random((S, A, S)) * (rng.random((S, A, S)) < sparsity)
    T[np.arange(S), :, rng.integers(0, S, size=S)] += 0.1  # no empty rows
    T /= T.sum(-1, keepdims=True)
    mean = rng.uniform(0.05, 0.95, size=(S, A, S))
    conc = np.where(rng.random((S, A, S)) < 0.5, rng.uniform(1, 10, size=(S, A, S)), 0.0)
    P0 = rng.random(S)
    return jaxmdp.custom_mdp(T, P0=P0 / P0.sum(), H=H, reward_mean=mean, reward_conc=conc)


#: Memory maps a test process may hold before :func:`_release_compiled_programs` drops JAX's compiled programs: well
#: under Linux's default ``vm.max_map_count`` of 65 530, which a worker that kept every program neared (49 222 seen).
MAP_BUDGET = 30_000


def memory_maps() -> int | None:
    """The number of memory maps this process holds (``/proc/self/maps``), or ``None`` where that cannot be read."""
    try:
        with open("/proc/self/maps", "rb") as f:
            return sum(1 for _ in f)
    except OSError:
        return None


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """After a test module, drop JAX's compiled programs if the process holds more than :data:`MAP_BUDGET` memory
    maps (always, where the count cannot be read). Every compiled CPU program keeps memory maps in the process; past
    Linux's limit XLA crashed while compiling (SIGSEGV or SIGABRT in ``backend_compile_and_load``, three full runs out
    of three when every module kept its programs). Below the budget the programs stay, so later modules reuse what
    earlier ones compiled (the runner's programs, the small programs of ``jnp`` operations)."""
    yield
    maps = memory_maps()
    if maps is None or maps > MAP_BUDGET:
        jax.clear_caches()
        gc.collect()


@pytest.fixture
def registry():
    """The agent registry (``agents``) with its entries and search spaces restored after the test: registering an
    agent changes them for the whole process."""
    import agents
    from agents import search_spaces

    entries, ranges = dict(agents.AGENTS._entries), dict(search_spaces._RANGES)
    yield agents
    agents.AGENTS._entries.clear()
    agents.AGENTS._entries.update(entries)
    search_spaces._RANGES.clear()
    search_spaces._RANGES.update(ranges)
