"""Registry of MDP families: ``make``, ``families`` and ``register`` (gymnax-style, with a did-you-mean hint)."""

from __future__ import annotations

import difflib
import inspect
from collections.abc import Callable

from jaxmdp._checks import did_you_mean
from jaxmdp.mdp import MDP

__all__ = ["make", "families", "register"]

Builder = Callable[..., MDP]
_REGISTRY: dict[str, Builder] = {}


def register(name: str, builder: Builder, *, overwrite: bool = False) -> None:
    """Register ``builder(*, episodic, seed, **params) -> MDP`` under ``name``."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"name must be a non-empty string; got {name!r}")
    if name in _REGISTRY and not overwrite:
        raise ValueError(f"family {name!r} is already registered (pass overwrite=True to replace it)")
    _REGISTRY[name] = builder


def families() -> tuple[str, ...]:
    """Names of the registered families."""
    return tuple(_REGISTRY)


def make(name: str, *, episodic: bool, seed: int, **params) -> MDP:
    """Build an MDP of family ``name``, e.g. ``make("RiverSwim", episodic=False, seed=0, size=10, p_lazy=0.1)``.

    Raises ``ValueError`` for an unknown family (suggesting the closest names) or invalid parameters, and
    :class:`~jaxmdp.NotEnoughMemory` (a ``ValueError``) before building anything when the MDP's arrays cannot
    fit in the memory available (a built-in family bounds its number of states from its size parameters,
    :meth:`~jaxmdp.mdp_families.Family.max_states`).
    """
    if name not in _REGISTRY:
        lowered = {k.lower(): k for k in _REGISTRY}
        close = difflib.get_close_matches(name.lower(), list(lowered), n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(repr(lowered[c]) for c in close)}?" if close else ""
        raise ValueError(f"unknown MDP family {name!r}{hint} Registered: {', '.join(_REGISTRY)}")
    builder = _REGISTRY[name]
    sig = inspect.signature(builder)
    if not any(p.kind is inspect.Parameter.VAR_KEYWORD for p in sig.parameters.values()):
        for key in params:
            if key not in sig.parameters:
                raise ValueError(f"{name} has no parameter {key!r}{did_you_mean(key, sig.parameters, 0.6)}")
    return builder(episodic=episodic, seed=seed, **params)
