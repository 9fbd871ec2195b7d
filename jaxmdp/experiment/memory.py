"""Will a compiled run fit in memory? A check before anything runs, instead of an allocator failure mid-run.

XLA knows, once a program is compiled, how much memory one execution needs: its arguments, outputs and temporary
buffers (``Compiled.memory_analysis()``, per device; arguments donated to outputs counted once). The runner
(:func:`jaxmdp.experiment.runner.run`) compares that with what the devices have before it starts, and raises
:class:`ProgramTooLarge` naming the remedy (fewer members per call) when it does not fit. On a CPU every shard's
loop runs in the same host memory, so the need is per device times the shards, against the host's available memory
(:func:`jaxmdp._memory.host_available_bytes`: ``MemAvailable``, else the physical memory, within the cgroup's and the
process's limits); on an accelerator it is per device against the device's ``bytes_limit``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import jax

from jaxmdp._memory import device_available_bytes, format_bytes, host_available_bytes, program_bytes

__all__ = ["ProgramTooLarge", "available_bytes", "program_bytes", "check_fits"]


class ProgramTooLarge(MemoryError):
    """A compiled program needs more memory than the devices have (:func:`check_fits`): ``needed`` and ``available``
    bytes, for all the shards together on a CPU, per device on an accelerator."""

    def __init__(self, message: str, needed: int, available: int):
        super().__init__(message)
        self.needed = needed
        self.available = available


def available_bytes(device: jax.Device | None = None) -> int | None:
    """Memory a program can use on ``device`` (default the first local device): the host's available memory for a
    CPU (:func:`jaxmdp._memory.host_available_bytes`: ``MemAvailable``, the cgroup's limit and the process's limits),
    the allocator's free bytes for an accelerator (:func:`jaxmdp._memory.device_available_bytes`); ``None`` when it
    cannot be told."""
    device = jax.local_devices()[0] if device is None else device
    if device.platform == "cpu":
        return host_available_bytes()
    return device_available_bytes(device)


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
            f"the {worst_name} program needs {format_bytes(worst)} on {where} but {format_bytes(available)} are "
            f"available{'; ' + remedy if remedy else ''}",
            worst,
            available,
        )
    return worst
