"""Will a compiled run fit in memory? A check before anything runs, instead of an allocator failure mid-run.

XLA knows, once a program is compiled, how much memory one execution needs: its arguments, outputs and temporary
buffers (``Compiled.memory_analysis()``, per device; arguments donated to outputs counted once). The runner
(:func:`jaxmdp.experiment.runner.run`) compares that with what the devices have before it starts, and raises
:class:`ProgramTooLarge` naming the remedy (fewer members per call) when it does not fit. On a CPU every shard's
loop runs in the same host memory, so the need is per device times the shards, against the host's available memory
(``MemAvailable`` of ``/proc/meminfo``, else the physical memory); on an accelerator it is per device against the
device's ``bytes_limit``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import jax

__all__ = ["ProgramTooLarge", "available_bytes", "program_bytes", "check_fits"]


class ProgramTooLarge(MemoryError):
    """A compiled program needs more memory than the devices have (:func:`check_fits`): ``needed`` and ``available``
    bytes, for all the shards together on a CPU, per device on an accelerator."""

    def __init__(self, message: str, needed: int, available: int):
        super().__init__(message)
        self.needed = needed
        self.available = available


def _host_available() -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def available_bytes(device: jax.Device | None = None) -> int | None:
    """Memory a program can use on ``device`` (default the first local device): the host's available memory for a
    CPU, the allocator's ``bytes_limit`` for an accelerator; ``None`` when it cannot be told."""
    device = jax.local_devices()[0] if device is None else device
    if device.platform == "cpu":
        return _host_available()
    stats = device.memory_stats() or {}
    limit = stats.get("bytes_limit")
    return None if limit is None else int(limit) - int(stats.get("bytes_in_use", 0))


def program_bytes(compiled: Any) -> int | None:
    """Bytes one execution of a compiled program needs on one device: arguments + outputs + temporaries - donated
    (aliased) buffers, from XLA's memory analysis; ``None`` if the backend gives none."""
    try:
        stats = compiled.memory_analysis()
    except (NotImplementedError, RuntimeError, AttributeError):
        return None
    if stats is None:
        return None
    return int(
        stats.argument_size_in_bytes + stats.output_size_in_bytes + stats.temp_size_in_bytes
        - stats.alias_size_in_bytes
    )


def _size(n: int) -> str:
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.2f} {unit}"
    return f"{n} bytes"


def check_fits(
    programs: Sequence[tuple[str, Any]], n_shards: int, *, limit: int | None = None, remedy: str = ""
) -> int | None:
    """Raise :class:`ProgramTooLarge` if one of the compiled ``(name, program)`` pairs needs more than ``limit``
    bytes (default :func:`available_bytes`); ``n_shards`` devices run each program at once. Returns the largest need
    (all shards together on a CPU), or ``None`` when the backend reports none. ``remedy`` ends the message."""
    device = jax.local_devices()[0]
    shared = device.platform == "cpu"  # host devices share one memory
    available = available_bytes(device) if limit is None else int(limit)
    worst, worst_name = None, ""
    for name, program in programs:
        need = program_bytes(program)
        if need is None:
            continue
        need *= n_shards if shared else 1
        if worst is None or need > worst:
            worst, worst_name = need, name
    if worst is not None and available is not None and worst > available:
        where = f"{n_shards} host devices together" if shared and n_shards > 1 else f"one {device.platform} device"
        raise ProgramTooLarge(
            f"the {worst_name} program needs {_size(worst)} on {where} but {_size(available)} are available"
            f"{'; ' + remedy if remedy else ''}",
            worst,
            available,
        )
    return worst
