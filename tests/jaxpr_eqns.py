"""Test helper: every equation of a jaxpr, those of its nested jaxprs (jit, scan, while, cond, custom rules) too."""

from collections.abc import Iterator
from typing import Any


def equations(jaxpr: Any) -> Iterator[Any]:
    """The equations of ``jaxpr`` (a ``Jaxpr`` or ``ClosedJaxpr``) and, depth first, of every jaxpr in their params."""
    jaxpr = getattr(jaxpr, "jaxpr", jaxpr)
    for eqn in jaxpr.eqns:
        yield eqn
        for value in eqn.params.values():
            for sub in value if isinstance(value, (tuple, list)) else (value,):
                sub = getattr(sub, "jaxpr", sub)
                if hasattr(sub, "eqns"):
                    yield from equations(sub)
