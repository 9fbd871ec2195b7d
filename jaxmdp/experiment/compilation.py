"""Compile once: a persistent JAX compilation cache for the scripts, and the time spent compiling.

Both change process-wide JAX state (its configuration, its monitoring listeners), so the library never calls them:
the entry points do, before anything compiles (the console commands and the command lines of
:mod:`hardness.analysis`).

* :func:`enable_compilation_cache` points JAX's persistent cache at a user cache folder (default
  ``<user cache dir>/jaxmdp/jax_compilation_cache``, e.g. ``~/.cache/jaxmdp/...`` on Linux), caches every program
  whatever its compile time, and bounds the folder (least recently used entries are evicted beyond
  :data:`MAX_CACHE_BYTES`). The environment variable ``JAXMDP_COMPILATION_CACHE`` turns it off (``0``, ``off``,
  ``false``, ``no``) or names another folder; the scripts' ``--no-compile-cache`` flag turns it off too.
* :func:`compile_stats` counts, from JAX's monitoring events, the wall time spent tracing, lowering and compiling
  (or loading from the cache; the persistent cache saves only this last phase) and the persistent cache's hits and
  misses since the first call; :func:`time_report` writes them beside the total time.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
from pathlib import Path

import jax
from jax import monitoring

__all__ = [
    "CACHE_ENV_VAR",
    "MAX_CACHE_BYTES",
    "CompileStats",
    "add_cache_flag",
    "compile_stats",
    "default_cache_dir",
    "enable_compilation_cache",
    "setup_compilation",
    "time_report",
]

#: Environment variable: ``0``/``off``/``false``/``no`` disables the cache, any other non-empty value is its folder.
CACHE_ENV_VAR = "JAXMDP_COMPILATION_CACHE"
#: Size bound of the cache folder (JAX evicts the least recently used entries beyond it).
MAX_CACHE_BYTES = 4 * 2**30
_OFF = {"0", "off", "false", "no"}

# JAX's monitoring events: durations of the three compile phases (their spans nest: a jit traced inside another
# records its own span inside the outer one) and the persistent cache's outcomes.
_PHASE_EVENTS = (
    "/jax/core/compile/jaxpr_trace_duration",
    "/jax/core/compile/jaxpr_to_mlir_module_duration",
    "/jax/core/compile/backend_compile_duration",
)
_PHASE_NAMES = dict(zip(_PHASE_EVENTS, ("trace", "lower", "backend")))
_HIT_EVENT = "/jax/compilation_cache/cache_hits"
_MISS_EVENT = "/jax/compilation_cache/cache_misses"
# Spans kept to recognise nesting: a span encloses only recent ones, so a short window suffices.
_SPAN_WINDOW = 64


def default_cache_dir() -> Path:
    """``<user cache dir>/jaxmdp/jax_compilation_cache``: ``$XDG_CACHE_HOME`` or ``~/.cache`` (Linux),
    ``~/Library/Caches`` (macOS), ``%LOCALAPPDATA%`` (Windows)."""
    if sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    elif os.name == "nt":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "jaxmdp" / "jax_compilation_cache"


def enable_compilation_cache(path: str | os.PathLike | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache in ``path`` (default: ``$JAXMDP_COMPILATION_CACHE`` or
    :func:`default_cache_dir`). Returns the folder, or None when the environment variable turns the cache off.

    Call it before the first compilation of the process (JAX decides once, at its first compile, whether a cache is
    used). Every program is cached, whatever its compile time (JAX's default skips those under a second, most of the
    scripts' programs); the folder is bounded by :data:`MAX_CACHE_BYTES`.
    """
    if path is None:
        env = os.environ.get(CACHE_ENV_VAR, "").strip()
        if env.lower() in _OFF:
            return None
        path = env or default_cache_dir()
    folder = Path(path).expanduser()
    folder.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    jax.config.update("jax_compilation_cache_max_size", MAX_CACHE_BYTES)
    return folder


class CompileStats:
    """Running totals of JAX's compile events (see :func:`compile_stats`); thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.seconds = 0.0
        self.phase_seconds = dict.fromkeys(_PHASE_NAMES.values(), 0.0)
        self.hits = 0
        self.misses = 0
        self._spans: list[tuple[float, float, str]] = []

    def _on_span(self, event: str, start: float, end: float, **_: object) -> None:
        if event not in _PHASE_EVENTS:
            return
        with self._lock:
            # Spans end inner first: the new span replaces the recent ones it encloses, so time counts once.
            while self._spans and self._spans[-1][0] >= start:
                s, e, phase = self._spans.pop()
                self.seconds -= e - s
                self.phase_seconds[phase] -= e - s
            phase = _PHASE_NAMES[event]
            self._spans.append((start, end, phase))
            self.seconds += end - start
            self.phase_seconds[phase] += end - start
            del self._spans[:-_SPAN_WINDOW]

    def _on_event(self, event: str, **_: object) -> None:
        if event in (_HIT_EVENT, _MISS_EVENT):
            with self._lock:
                if event == _HIT_EVENT:
                    self.hits += 1
                else:
                    self.misses += 1

    def snapshot(self) -> dict[str, float]:
        """``{"compile_s", "trace_s", "lower_s", "backend_s", "cache_hits", "cache_misses"}`` so far (the phases
        split ``compile_s``, each span counted in the outermost phase that encloses it)."""
        with self._lock:
            phases = {f"{name}_s": v for name, v in self.phase_seconds.items()}
            return {"compile_s": self.seconds, **phases, "cache_hits": self.hits, "cache_misses": self.misses}


_STATS: CompileStats | None = None
_STATS_LOCK = threading.Lock()


def compile_stats() -> CompileStats:
    """The process's :class:`CompileStats`, listening to JAX's monitoring events from the first call on (one
    listener pair per process, registered by that call; totals of compilations before it are not seen).

    ``compile_s`` is the wall time of the union of the trace, lowering and backend-compile spans (a cache hit counts
    its load time); ``cache_hits``/``cache_misses`` count the persistent cache's lookups.
    """
    global _STATS
    with _STATS_LOCK:
        if _STATS is None:
            _STATS = CompileStats()
            monitoring.register_event_time_span_listener(_STATS._on_span)
            monitoring.register_event_listener(_STATS._on_event)
        return _STATS


def add_cache_flag(parser: argparse.ArgumentParser) -> None:
    """Add ``--no-compile-cache`` to a script's parser (see :func:`setup_compilation`)."""
    parser.add_argument(
        "--no-compile-cache",
        action="store_true",
        help=f"do not use the persistent compilation cache (default folder {default_cache_dir()}; "
        f"{CACHE_ENV_VAR}=0 also turns it off, another value names the folder)",
    )


def setup_compilation(no_cache: bool = False) -> tuple[Path | None, CompileStats]:
    """A script's first call: the cache (unless ``no_cache``) and the compile-time counters.

    Returns ``(cache folder or None, stats)``.
    """
    folder = None if no_cache else enable_compilation_cache()
    return folder, compile_stats()


def time_report(total_s: float, snapshot: dict[str, float], folder: Path | None) -> str:
    """One line: the total wall time, the part spent compiling and the cache's hits and misses."""
    cache = f"cache {folder}: {snapshot['cache_hits']} hits, {snapshot['cache_misses']} misses" if folder else "no cache"
    phases = ", ".join(f"{label} {snapshot[key]:.1f} s" for label, key in
                       (("trace", "trace_s"), ("lower", "lower_s"), ("XLA", "backend_s")))
    return (
        f"time: {total_s:.1f} s, of which compiling {snapshot['compile_s']:.1f} s ({phases}) and running "
        f"{max(total_s - snapshot['compile_s'], 0.0):.1f} s ({cache})"
    )
