"""Refuse a construction that cannot fit in memory, before it allocates anything large.

Every constructor that allocates per-state arrays (:func:`jaxmdp.make` and the families, :func:`jaxmdp.custom_mdp`,
:func:`jaxmdp.stack` / :func:`jaxmdp.pad`, :func:`jaxmdp.emission_table` / :func:`jaxmdp.block_mdp`, the measures of
many MDPs) estimates from the sizes it was given the bytes it will hold at once, and calls :func:`check_memory` first.
A need above what is available raises :class:`NotEnoughMemory` (a ``ValueError``, and a ``MemoryError``) naming the
sizes, the bytes needed, the bytes available and the remedy, instead of an allocation that the kernel ends by killing
the process.

The rule for an estimate: it counts the arrays the construction holds at its peak (dense ``[S, A, S]`` kernels
dominate), so it is never below the bytes of the arrays it returns, and it is not padded beyond that peak, so that it
refuses nothing that fits.

Available host memory (:func:`host_available_bytes`) is the smallest of: ``MemAvailable`` of ``/proc/meminfo`` (else
the physical memory), what the process's memory cgroup (v2 ``memory.max``, v1 ``memory.limit_in_bytes``) leaves
beyond its current usage, and what the address-space and data-segment limits (``RLIMIT_AS``, ``RLIMIT_DATA``) leave
beyond the process's current sizes. On an accelerator the arrays a constructor places on the device are compared with
the device's free bytes (``bytes_limit - bytes_in_use``); on a CPU host and device arrays share the host memory.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

__all__ = [
    "NotEnoughMemory",
    "host_available_bytes",
    "device_available_bytes",
    "format_bytes",
    "check_memory",
    "program_bytes",
    "check_program",
    "DEFAULT_REMEDY",
]

#: The remedy a refusal names unless its caller gives its own.
DEFAULT_REMEDY = "use smaller sizes, or a machine with more memory"


class NotEnoughMemory(ValueError, MemoryError):
    """A construction would need more memory than is available (:func:`check_memory`); ``needed`` and
    ``available`` are bytes, ``where`` is ``"host"`` or the device's platform."""

    def __init__(self, message: str, needed: int, available: int, where: str = "host"):
        super().__init__(message)
        self.needed = int(needed)
        self.available = int(available)
        self.where = where


def _read_int(path: str) -> int | None:
    try:
        with open(path) as f:
            text = f.read().strip()
    except OSError:
        return None
    if text == "max":
        return None
    try:
        return int(text)
    except ValueError:
        return None


def _meminfo() -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def _cgroup_left() -> int | None:
    """What the process's memory cgroup leaves: its limit minus its usage (v2, else v1), the smallest over the
    directories where the cgroup may be mounted (its own path, or the mount root inside a container)."""
    try:
        with open("/proc/self/cgroup") as f:
            entries = [line.rstrip("\n").split(":", 2) for line in f]
    except OSError:
        return None
    candidates: list[tuple[str, str, str]] = []
    for entry in entries:
        if len(entry) != 3:
            continue
        _, controllers, path = entry
        path = path.lstrip("/")
        if controllers == "":  # cgroup v2
            for root in ("/sys/fs/cgroup", "/sys/fs/cgroup/unified"):
                for d in (os.path.join(root, path), root):
                    candidates.append((d, "memory.max", "memory.current"))
        elif "memory" in controllers.split(","):  # cgroup v1
            root = "/sys/fs/cgroup/memory"
            for d in (os.path.join(root, path), root):
                candidates.append((d, "memory.limit_in_bytes", "memory.usage_in_bytes"))
    left = None
    for d, limit_file, usage_file in dict.fromkeys(candidates):
        limit = _read_int(os.path.join(d, limit_file))
        if limit is None or limit >= 2**60:  # no limit ("max", or v1's page-rounded LONG_MAX)
            continue
        usage = _read_int(os.path.join(d, usage_file)) or 0
        room = max(limit - usage, 0)
        left = room if left is None else min(left, room)
    return left


def _rlimit_left() -> int | None:
    """What ``RLIMIT_AS`` and ``RLIMIT_DATA`` leave beyond the process's current ``VmSize`` and ``VmData``."""
    try:
        import resource
    except ImportError:  # pragma: no cover - not POSIX
        return None
    sizes: dict[str, int] = {}
    try:
        with open("/proc/self/status") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key in ("VmSize", "VmData"):
                    sizes[key] = int(value.split()[0]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    left = None
    for limit_name, used_name in (("RLIMIT_AS", "VmSize"), ("RLIMIT_DATA", "VmData")):
        soft, _ = resource.getrlimit(getattr(resource, limit_name))
        if soft == resource.RLIM_INFINITY or used_name not in sizes:
            continue
        room = max(int(soft) - sizes[used_name], 0)
        left = room if left is None else min(left, room)
    return left


def host_available_bytes() -> int | None:
    """Host memory a new allocation can use: the smallest of ``MemAvailable`` (else the physical memory), the memory
    cgroup's limit minus its usage and the room left by ``RLIMIT_AS`` / ``RLIMIT_DATA``; ``None`` when none can be
    told."""
    values = [v for v in (_meminfo(), _cgroup_left(), _rlimit_left()) if v is not None]
    return min(values) if values else None


def device_available_bytes(device: Any) -> int | None:
    """Free bytes of an accelerator (``bytes_limit - bytes_in_use`` of its allocator); ``None`` for a CPU device
    (which shares the host memory) or when the backend does not say."""
    if device.platform == "cpu":
        return None
    try:
        stats = device.memory_stats() or {}
    except (NotImplementedError, RuntimeError, AttributeError):
        return None
    limit = stats.get("bytes_limit")
    return None if limit is None else int(limit) - int(stats.get("bytes_in_use", 0))


def format_bytes(n: int) -> str:
    """``n`` bytes in the largest binary unit of at least one (``"1.50 GiB"``)."""
    for unit, scale in (("EiB", 2**60), ("PiB", 2**50), ("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.2f} {unit}"
    return f"{int(n)} bytes"


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


def _default_device() -> Any:
    import jax

    return jax.local_devices()[0]


def check_memory(
    needed: int,
    what: str,
    sizes: Mapping[str, Any] = (),  # type: ignore[assignment]
    *,
    detail: str = "",
    device_bytes: int = 0,
    remedy: str = DEFAULT_REMEDY,
    available: int | None = None,
) -> None:
    """Raise :class:`NotEnoughMemory` unless a construction fits: ``needed`` bytes of host memory at its peak, of which
    ``device_bytes`` end on the default device.

    On a CPU device the whole ``needed`` is compared with :func:`host_available_bytes` (or ``available`` when
    given); on an accelerator ``needed - device_bytes`` is compared with the host's and ``device_bytes`` with the
    device's free bytes. ``what`` names the construction (``"jaxmdp.make('DeepSea')"``), ``sizes`` the parameters
    it was estimated from (``{"size": 100000}``) and ``detail`` what they imply (``"at most 5000050000 states, 2
    actions"``); all appear in the message with the bytes needed, the bytes available and ``remedy``. Nothing is
    checked when the memory cannot be told.
    """
    needed, device_bytes = int(needed), int(device_bytes)
    described = ", ".join(f"{k}={v}" for k, v in dict(sizes).items())
    subject = f"{what} with {described}" if described else what
    subject += f" ({detail})" if detail else ""
    host_need, device = needed, None
    if device_bytes and available is None:
        device = _default_device()
        if device.platform != "cpu":
            host_need = max(needed - device_bytes, 0)
    checks = [("host", host_need, host_available_bytes() if available is None else int(available))]
    if device is not None and device.platform != "cpu":
        checks.append((device.platform, device_bytes, device_available_bytes(device)))
    for where, need, have in checks:
        if have is not None and need > have:
            memory = "host memory" if where == "host" else f"{where} device memory"
            raise NotEnoughMemory(
                f"{subject} needs about {format_bytes(need)} ({need} bytes) of {memory} but {format_bytes(have)} "
                f"({have} bytes) is available; {remedy}",
                need,
                have,
                where,
            )


def check_program(
    compiled: Any,
    what: str,
    sizes: Mapping[str, Any] = (),  # type: ignore[assignment]
    *,
    detail: str = "",
    remedy: str = DEFAULT_REMEDY,
    available: int | None = None,
) -> int | None:
    """:func:`check_memory` for a compiled program (``jit(f).lower(...).compile()``) before it runs: its
    :func:`program_bytes` against the default device's memory (the host's for a CPU). Returns the bytes, or ``None``
    when the backend reports none (nothing is checked then)."""
    need = program_bytes(compiled)
    if need is not None:
        check_memory(need, what, sizes, detail=detail, device_bytes=need, remedy=remedy, available=available)
    return need
