"""Frozen dataclasses that are JAX pytrees: the containers of every MDP, agent state, hyperparameter set and result.

A class made with :class:`PyTreeNode` (subclass it) or :func:`dataclass` (decorate it) is a frozen dataclass
registered with :func:`jax.tree_util.register_dataclass`:

* a *data* field (the default) is a pytree child: ``jax.tree.map``, ``vmap`` and ``jit`` see its leaves;
* a *static* field, ``field(pytree_node=False)``, is part of the tree structure: it is hashed and compared with the
  treedef, so ``jit`` compiles once per distinct value (sizes, variants, flags) and tree maps leave it alone.

Instances are immutable; ``x.replace(**changes)`` returns a copy with some fields changed
(:func:`dataclasses.replace`). Fields, defaults, positional or keyword construction and inheritance from a parent
class are those of :mod:`dataclasses`; a subclass of a ``PyTreeNode`` class is a ``PyTreeNode`` with the parent's
fields first. The static flag is stored as the field's metadata ``"pytree_node"``, so code that inspects
``dataclasses.fields(x)`` reads the same as for ``flax.struct``.

These are the semantics of ``flax.struct``, which the package used before: classes written for it work unchanged
with this module, and a ``flax.struct`` twin of a class has the same leaves and the same static values. The core
(MDPs, measures, tabular agents) defines its own because flax brings optax, orbax-checkpoint and tensorstore into
the install, none of which it uses; flax is a dependency of the deep agents only (the ``deep`` extra). Your own agent
can use either.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, TypeVar, dataclass_transform, overload

import jax

__all__ = ["PyTreeNode", "dataclass", "field"]

_T = TypeVar("_T")
_Node = TypeVar("_Node", bound="PyTreeNode")

#: The metadata key that marks a static field (``False``); the same key as flax.struct's.
_PYTREE_NODE = "pytree_node"
#: Set in a class's own ``__dict__`` once it is registered, so that registering it twice is a no-op.
_REGISTERED = "_jaxmdp_struct"


def field(pytree_node: bool = True, *, metadata: dict | None = None, **kwargs: Any) -> Any:
    """A dataclass field; ``pytree_node=False`` makes it static (part of the treedef, hashed, not a leaf).

    The other arguments (``default``, ``default_factory``, ``repr``, ...) are those of :func:`dataclasses.field`.
    """
    return dataclasses.field(metadata={**(metadata or {}), _PYTREE_NODE: pytree_node}, **kwargs)


def _replace(self: _T, **changes: Any) -> _T:
    """A copy with the given fields changed (:func:`dataclasses.replace`)."""
    return dataclasses.replace(self, **changes)  # type: ignore[type-var]


@overload
def dataclass(cls: type[_T], /, **kwargs: Any) -> type[_T]: ...
@overload
def dataclass(cls: None = None, /, **kwargs: Any) -> Callable[[type[_T]], type[_T]]: ...


@dataclass_transform(frozen_default=True, field_specifiers=(field, dataclasses.field))
def dataclass(cls: type[_T] | None = None, /, **kwargs: Any) -> Any:
    """Make ``cls`` a frozen dataclass registered as a pytree, with a ``replace`` method.

    ``kwargs`` go to :func:`dataclasses.dataclass` (``frozen=True`` unless given); ``@dataclass(kw_only=True)``
    works too. Fields made with ``field(pytree_node=False)`` are static, every other field is data. A class already
    registered by this module is returned as it is.
    """
    if cls is None:
        return lambda c: dataclass(c, **kwargs)
    if _REGISTERED in cls.__dict__:
        return cls
    kwargs.setdefault("frozen", True)
    cls = dataclasses.dataclass(**kwargs)(cls)
    fields = dataclasses.fields(cls)
    data = [f.name for f in fields if f.metadata.get(_PYTREE_NODE, True)]
    meta = [f.name for f in fields if not f.metadata.get(_PYTREE_NODE, True)]
    jax.tree_util.register_dataclass(cls, data_fields=data, meta_fields=meta)
    if not hasattr(cls, "replace"):  # a PyTreeNode subclass inherits it (or its own override)
        cls.replace = _replace  # type: ignore[attr-defined]
    setattr(cls, _REGISTERED, True)
    return cls


@dataclass_transform(frozen_default=True, field_specifiers=(field, dataclasses.field))
class PyTreeNode:
    """Base class: every subclass is made a pytree dataclass by :func:`dataclass` (class keywords go to it).

    In ``class Counts(PyTreeNode)`` with fields ``visits: jax.Array`` and ``n_states: int =
    field(pytree_node=False)``, ``visits`` is a leaf and ``n_states`` static (``jit`` compiles once per value).
    """

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__()
        dataclass(cls, **kwargs)

    def replace(self: _Node, **changes: Any) -> _Node:
        """A copy with the given fields changed (:func:`dataclasses.replace`)."""
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]
