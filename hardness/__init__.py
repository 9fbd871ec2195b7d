"""Hardness measures of MDPs (paper §2.2): diameter, environmental value norm, sum of reciprocal sub-optimality gaps;
and two that the paper's Table 1 marks as not known to be computable: the mixing time of a policy's chain
(:func:`mixing_time`) and the distribution mismatch coefficient (:func:`distribution_mismatch`); and two from regret
bounds of the average-reward literature: the span of the optimal bias (:func:`bias_span`, Bartlett & Tewari 2009) and
the gap constant of Burnetas & Katehakis's lower bound (:func:`gap_constant`).

Every measure takes one :class:`jaxmdp.MDP` and returns a :class:`MeasureResult` (``value``, ``converged``,
``finite``); ``jax.vmap`` runs it over a stacked batch (:func:`jaxmdp.stack`), and padding changes nothing;
:func:`measures_many` computes all three for a collection of MDPs of different sizes (size buckets, each mapped with
``lax.map`` rather than vmapped, because in lockstep every member runs until the slowest has converged and batched
gathers are slow on a CPU; docs/performance.md, Hardness measures).
``variant="paper"`` (default) computes the paper's definitions exactly; ``variant="colosseum"`` reproduces the
reference package's procedures and numbers (docs/measures.md). :func:`normalize` is the min-max scaling of App. E.
"""

from hardness.batched import measures_many
from hardness.bias_span import bias_span
from hardness.diameter import diameter, strongly_connected
from hardness.gap_constant import gap_constant
from hardness.gaps import suboptimality_gaps, sum_reciprocal_gaps
from hardness.measures import HardnessMeasures, measures, normalize
from hardness.mismatch import distribution_mismatch
from hardness.mixing import mixing_time
from hardness.result import MeasureResult
from hardness.value_norm import deterministic_base, value_norm

__all__ = [
    "MeasureResult",
    "HardnessMeasures",
    "diameter",
    "value_norm",
    "sum_reciprocal_gaps",
    "measures",
    "measures_many",
    "normalize",
    "suboptimality_gaps",
    "strongly_connected",
    "deterministic_base",
    "mixing_time",
    "distribution_mismatch",
    "bias_span",
    "gap_constant",
]
