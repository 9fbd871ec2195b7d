"""The three measures of many MDPs of different sizes at once: size buckets, one compiled program per bucket.

``jax.vmap(hardness.measures)`` over one :func:`jaxmdp.stack` is right for a grid of equal shapes (a ``p_rand``
sweep). A heterogeneous collection, such as the 80 MDPs of the benchmark (15 to 948 states, 2 to 6 actions, 1 to 8
successors), pays twice in one padded stack: every member does the all-pairs work of the largest one
(``S^2 A K`` per backup), and under ``vmap`` every iterative solver runs until the slowest member has converged.
:func:`measures_many` avoids both: it splits the members by setting and then into :func:`jaxmdp.size_buckets`
(minimal padded work), and maps the measures over each bucket's stack with ``lax.map``, so that each member's
iterations stop at its own convergence. ``batch_size > 1`` vmaps chunks of that many members instead (for
accelerators, where lockstep members run in parallel). Values are those of :func:`hardness.measures` (padding
changes no measure).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import chex
import jax
import numpy as np

from hardness.measures import HardnessMeasures, measures
from jaxmdp._checks import Variant, check_int, check_range, check_variant
from jaxmdp._memory import check_program
from jaxmdp.batching import size_buckets, stack
from jaxmdp.episodic import continuous_form, stack_continuous_forms
from jaxmdp.mdp import MDP

__all__ = ["measures_many", "map_measures"]


@functools.partial(jax.jit, static_argnames=("gamma", "variant", "batch_size"))
def map_measures(
    batch: MDP, forms: Any = None, gamma: float = 0.99, variant: str = "paper", batch_size: int = 1
) -> HardnessMeasures:
    """:func:`hardness.measures` of every member of a stacked ``batch`` (``forms``: the stacked continuous forms of
    an episodic batch under ``variant="colosseum"``, else None), mapped with ``lax.map`` so that each member's
    solvers stop at its own convergence; ``batch_size`` members per step in lockstep. One compilation per shape."""
    chex.assert_rank(batch.T, 4, custom_message="batch: a stacked MDP, T [M, S, A, S] (jaxmdp.stack)")

    def one(args):
        m, cf = args
        return measures(m, gamma, variant=variant, continuous_form=cf)

    return jax.lax.map(one, (batch, forms), batch_size=batch_size)


def measures_many(
    mdps: Sequence[MDP],
    gamma: float = 0.99,
    *,
    variant: Variant = "paper",
    n_buckets: int = 8,
    batch_size: int = 1,
) -> HardnessMeasures:
    """:func:`hardness.measures` of every MDP of ``mdps`` (episodic and continuous ones may be mixed), as one
    :class:`~hardness.HardnessMeasures` whose arrays have a leading axis in the order of ``mdps``.

    Args:
      mdps: single (unstacked) MDPs of any sizes.
      gamma: discount of the value norm and the gap sum, in ``(0, 1)``.
      variant: ``"paper"`` or ``"colosseum"``, as in :func:`hardness.measures`.
      n_buckets: most stacks (hence compiled programs) per setting; more buckets mean less padding and more
        compilations (module docstring).
      batch_size: members per ``lax.map`` step; ``1`` runs them one after another (best on CPU), larger values
        vmap that many in lockstep.

    Raises:
      ValueError: invalid arguments; :class:`~jaxmdp.NotEnoughMemory` (a ``ValueError``) when a bucket's
        stack (:func:`jaxmdp.stack`) or its compiled program (XLA's memory analysis) needs more memory than is
        available, before either is allocated or run.
    """
    mdps = list(mdps)
    if not mdps:
        raise ValueError("mdps must hold at least one MDP")
    if any(m.T.ndim != 3 for m in mdps):
        raise ValueError("mdps must be single MDPs, not stacked batches")
    check_variant(variant)
    check_range("gamma", gamma, 0.0, 1.0, low_open=True, high_open=True)
    batch_size = check_int("batch_size", batch_size)
    parts: list[tuple[np.ndarray, HardnessMeasures]] = []
    for is_episodic in (False, True):
        idx = [i for i, m in enumerate(mdps) if m.episodic == is_episodic]
        if not idx:
            continue
        for group in size_buckets([mdps[i] for i in idx], n_buckets):
            members = [mdps[idx[g]] for g in group]
            forms = None
            if variant == "colosseum" and is_episodic:
                forms = stack_continuous_forms([continuous_form(m) for m in members])
            batch = stack(members).strip()
            # Compiled ahead of time so that its memory need (the per-target arrays of the solvers, e.g. [H, S, S]
            # in the episodic diameter) is checked before it runs.
            program = map_measures.lower(batch, forms, float(gamma), variant, int(batch_size)).compile()
            check_program(
                program,
                "hardness.measures_many",
                {"members": len(members), "S": batch.n_states, "A": batch.n_actions, "H": batch.H},
                detail=f"the measures of one size bucket, {batch_size} member(s) at a time",
                remedy="measure fewer or smaller MDPs per call, a smaller batch_size, more n_buckets, "
                "or use a machine with more memory",
            )
            out = program(batch, forms)
            parts.append((np.asarray([idx[g] for g in group]), out))
    where = np.concatenate([p[0] for p in parts])
    inverse = np.empty_like(where)
    inverse[where] = np.arange(len(where))
    # Reordered on the host: eager device concatenations and gathers would compile a program per array shape.
    return jax.tree.map(
        lambda *xs: jax.device_put(np.concatenate([np.asarray(x) for x in xs])[inverse]), *[p[1] for p in parts]
    )
