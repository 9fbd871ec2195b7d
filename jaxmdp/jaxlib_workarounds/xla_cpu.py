"""Guard against a silent miscompilation of jaxlib's CPU backend by its YNNPACK fusions (docs/performance.md,
jaxlib workarounds): some elementwise-then-reduce fusions can return wrong numbers without an error.

Importing :mod:`jaxmdp` adds ``--xla_cpu_experimental_ynn_fusion_type=`` (empty: no YNNPACK fusions) to
``XLA_FLAGS`` when all of these hold: the installed jaxlib is an affected version (:func:`affected`; other versions
either lack the fusions and would abort on the flag, or are outside the range that tests/test_xla_cpu.py keeps true),
the user has not set that flag themselves, ``JAXMDP_NO_XLA_GUARD`` is not set to a non-empty value other than ``0``
(the opt-out), and no JAX backend exists yet (XLA reads the flags once, when the first backend is created). When it
adds the flag it says so on the ``jaxmdp`` logger (level INFO). If a backend already exists the flag cannot take
effect any more and a ``RuntimeWarning`` says so: import jaxmdp before running any JAX computation.

Whether a backend exists has no public JAX API; the check uses ``jax._src.xla_bridge.backends_are_initialized`` and,
should that private function move, assumes no backend yet (the flag is then added, and at worst has no effect).
"""

from __future__ import annotations

import logging
import os
import re
import warnings

__all__ = ["YNN_FLAG", "OPT_OUT_VARIABLE", "affected", "disable_ynn_fusion", "ynn_fusion_disabled"]

#: The XLA option; an empty value disables every YNNPACK fusion on CPU.
YNN_FLAG = "--xla_cpu_experimental_ynn_fusion_type"

#: Set this environment variable (to anything but ``""`` or ``"0"``) to leave ``XLA_FLAGS`` alone.
OPT_OUT_VARIABLE = "JAXMDP_NO_XLA_GUARD"

# The affected jaxlib versions, [_FIRST_AFFECTED, _FIRST_UNAFFECTED) (docs/performance.md, jaxlib workarounds);
# tests/test_xla_cpu.py fails when the installed jaxlib's behaviour and this range disagree.
_FIRST_AFFECTED = (0, 10, 2)
_FIRST_UNAFFECTED = (0, 12, 0)

_log = logging.getLogger("jaxmdp")


def _version_tuple(version: str) -> tuple[int, ...]:
    parts = []
    for piece in version.split(".")[:3]:
        match = re.match(r"\d+", piece)  # "0rc1" -> 0
        parts.append(int(match.group()) if match else 0)
    return tuple(parts)


def affected(version: str) -> bool:
    """Whether jaxlib ``version`` is one of the versions with the YNNPACK miscompilation (module docstring)."""
    return _FIRST_AFFECTED <= _version_tuple(version) < _FIRST_UNAFFECTED


def ynn_fusion_disabled() -> bool:
    """Whether ``XLA_FLAGS`` currently carries the YNNPACK option (set by us or by the user)."""
    return YNN_FLAG in os.environ.get("XLA_FLAGS", "")


def _opted_out() -> bool:
    return os.environ.get(OPT_OUT_VARIABLE, "") not in ("", "0")


def _backend_exists() -> bool:
    try:
        from jax._src import xla_bridge
    except ImportError:  # pragma: no cover - a JAX version that moved it
        return False
    check = getattr(xla_bridge, "backends_are_initialized", None)
    return bool(check()) if check is not None else False


def disable_ynn_fusion() -> bool:
    """Add the flag to ``XLA_FLAGS`` if needed, wanted and still effective (module docstring); returns whether it
    was added."""
    import jaxlib

    if not affected(jaxlib.__version__) or ynn_fusion_disabled() or _opted_out():
        return False
    if _backend_exists():
        warnings.warn(
            "jaxmdp was imported after JAX created its backend, so it could not disable the YNNPACK fusions of "
            f"jaxlib {jaxlib.__version__}, which can silently return wrong numbers on CPU (jax-ml/jax#39103). "
            f"Import jaxmdp first, or set XLA_FLAGS={YNN_FLAG}= yourself.",
            RuntimeWarning,
            stacklevel=3,
        )
        return False
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {YNN_FLAG}=".strip()
    _log.info(
        "jaxmdp: added %s= to XLA_FLAGS (jaxlib %s miscompiles some CPU reductions with YNNPACK fusions, "
        "jax-ml/jax#39103); set %s=1 to opt out",
        YNN_FLAG, jaxlib.__version__, OPT_OUT_VARIABLE,
    )
    return True
