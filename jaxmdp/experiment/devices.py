"""One lockstep loop per CPU core: how many host devices XLA exposes (for the runner's ``shards``).

XLA's CPU backend runs one compiled loop on one core; :func:`jaxmdp.experiment.runner.run` splits the members over
the local devices, and a CPU has one device unless ``XLA_FLAGS`` asks for more. XLA reads the flags once, when JAX
creates its backend, so :func:`use_every_core` must run before the first JAX computation: it is meant for the top of
an entry point (a script), not for library code.
"""

from __future__ import annotations

import os

__all__ = ["DEVICE_COUNT_FLAG", "use_every_core"]

#: The XLA option that sets the number of host (CPU) devices.
DEVICE_COUNT_FLAG = "--xla_force_host_platform_device_count"


def use_every_core(n_devices: int | None = None) -> bool:
    """Ask XLA for ``n_devices`` host devices (default ``os.cpu_count()``) through ``XLA_FLAGS``, unless the flag is
    already set (the user's choice wins). Returns whether the flag was added. Call it before any JAX computation."""
    flags = os.environ.get("XLA_FLAGS", "")
    if DEVICE_COUNT_FLAG in flags:
        return False
    n = (os.cpu_count() or 1) if n_devices is None else n_devices
    os.environ["XLA_FLAGS"] = f"{flags} {DEVICE_COUNT_FLAG}={n}".strip()
    return True
