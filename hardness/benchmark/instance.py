"""One MDP of a named benchmark set (:mod:`hardness.benchmark.sets`): a family and its parameters, built per seed.

Its own module so that the sets and the search samplers (:mod:`hardness.benchmark.samplers`, which draws instances
for the search sets) both import it without importing each other.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jaxmdp
from hardness.benchmark.suite import BenchmarkEntry

__all__ = ["Instance"]


@dataclasses.dataclass(frozen=True)
class Instance:
    """One MDP of a named set: a family and its constructor parameters; :meth:`build` makes the MDP of a seed.

    Attributes:
      set_name: the set it belongs to.
      label: unique within the set, e.g. ``"DeepSea/prms_0"`` (benchmark MDPs) or ``"DeepSea/sample_0"``.
      family, episodic, params: what :func:`jaxmdp.make` receives (``params`` as sorted-by-order key/value pairs).
      entry: the :class:`~hardness.benchmark.suite.BenchmarkEntry` of a benchmark or quick-test MDP (its reference
        ``S``, ``H``, class and cached measures for seed 0), ``None`` for a sampled one.
    """

    set_name: str
    label: str
    family: str
    episodic: bool
    params: tuple[tuple[str, Any], ...]
    entry: BenchmarkEntry | None = None

    @property
    def name(self) -> str:
        return f"{self.set_name}/{self.label}"

    def kwargs(self) -> dict[str, Any]:
        return dict(self.params)

    def build(self, seed: int) -> jaxmdp.MDP:
        """The MDP of ``seed`` (the reference builds the MDP of experiment seed ``k`` with seed ``k``)."""
        return jaxmdp.make(self.family, episodic=self.episodic, seed=int(seed), **self.kwargs())
