"""What every console command shares: the ``--no-compile-cache`` flag and the closing compile-time line."""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from collections.abc import Iterator

from jaxmdp.experiment import compilation


def add_cache_flag(parser: argparse.ArgumentParser) -> None:
    """``--no-compile-cache`` (:func:`jaxmdp.experiment.compilation.add_cache_flag`)."""
    compilation.add_cache_flag(parser)


@contextlib.contextmanager
def compile_report(no_cache: bool) -> Iterator[None]:
    """Turn on the persistent compilation cache (unless ``no_cache``) and count compile time; when the block ends
    without an error, write the wall time and the part spent compiling to stderr. Enter it before anything compiles."""
    folder, stats = compilation.setup_compilation(no_cache)
    start = time.perf_counter()
    yield
    print(compilation.time_report(time.perf_counter() - start, stats.snapshot(), folder), file=sys.stderr)
