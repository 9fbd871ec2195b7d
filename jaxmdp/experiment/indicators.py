"""Exact expected-regret indicators of an agent's current policy (paper App. A.1 and App. E; docs/measures.md §6).

An agent exposes its current best policy estimate ``pi_t`` (``[S, A]`` continuous, ``[H, S, A]`` episodic). The
indicators evaluate it *exactly* (no sampling) on the true MDP:

* **Episodic** (finite-horizon policy evaluation, :func:`~jaxmdp.dynamic_programming.finite_horizon_policy_evaluation`):
  the per-episode regret is ``Delta = sum_s P0(s) (V*_0(s) - V^pi_0(s))`` (the paper's regret of a policy, an
  expectation over the start distribution) and the per-step regret ``r_t = Delta / H``. The normalised regret is
  ``Delta / sum_s P0(s) (V*_0(s) - V^-_0(s))`` with ``pi^-`` the value-minimising policy (App. E), and the per-step
  expected reward ``rho_t = sum_s P0(s) V^pi_0(s) / H``.
  ``variant="colosseum"`` reproduces the reference (docs/measures.md §6.2, [quirk]): ``Delta`` and its normaliser are
  taken at ``s0``, the start state of the most recent episode (the one in progress, or the one the logged step just
  ended), ``Delta(s0) = max(0, V*_0(s0) - V^pi_0(s0))``.
* **Continuous**: ``rho_t = rho^pi(s)``, the exact long-run average reward of ``pi`` from the current state ``s``
  (:func:`~jaxmdp.dynamic_programming.gain_vector`, which also handles multichain policies), and
  ``r_t = max(0, rho* - rho_t)``, normalised by ``rho* - rho^-``. ``rho*`` and ``rho^-`` come from
  :func:`jaxmdp.reference_values`: gain-optimal / gain-minimal policies by default (the paper), the greedy policies of
  the ``gamma = 0.99`` discounted values with ``variant="colosseum"`` (docs/measures.md §2.1, [paper≠code]); the
  colosseum variant also zeroes regrets ``<= 1e-3`` as the reference does. ``rho*`` is the optimal gain from ``P0``,
  which is the optimal gain from every state in a weakly communicating MDP.

When the normaliser vanishes (``<= 1e-6 (1 + |optimum|)``: every policy is optimal up to float precision) the
normalised regret is defined as 0, the value of the limit, instead of a ratio of round-off errors.

The baselines of the reference's CSV (random, worst and optimal policies, docs/measures.md §6.3) are linear in the step
count; :func:`baseline_columns` computes them from the per-step constants of :class:`IndicatorConstants`.
"""

from __future__ import annotations


import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp import dynamic_programming as dp
from jaxmdp import struct
from jaxmdp._checks import Variant, check_variant
from jaxmdp.mdp import MDP
from jaxmdp.values import reference_values

__all__ = [
    "IndicatorConstants",
    "Instant",
    "indicator_constants",
    "policy_values",
    "ITERATIVE_GAIN_SWEEPS",
    "ITERATIVE_GAIN_GIVE_UP",
    "instant_from_values",
    "instantaneous",
    "CSV_COLUMNS",
    "AGENT_COLUMNS",
    "baseline_columns",
]


#: Regrets at most this large are set to zero by the reference's continuous indicator (docs/measures.md §6.2).
COLOSSEUM_REGRET_ATOL = 1e-3
# Relative size below which a normaliser counts as zero.
_DEGENERATE_RTOL = 1e-6

#: The reference's CSV columns, in its order (docs/benchmark.md §2).
CSV_COLUMNS = (
    "steps",
    "cumulative_regret",
    "cumulative_reward",
    "cumulative_expected_reward",
    "normalized_cumulative_regret",
    "normalized_cumulative_reward",
    "normalized_cumulative_expected_reward",
    "random_cumulative_regret",
    "random_cumulative_expected_reward",
    "random_normalized_cumulative_regret",
    "random_normalized_cumulative_expected_reward",
    "worst_cumulative_regret",
    "worst_cumulative_expected_reward",
    "worst_normalized_cumulative_regret",
    "worst_normalized_cumulative_expected_reward",
    "optimal_cumulative_expected_reward",
    "optimal_normalized_cumulative_expected_reward",
    "steps_per_second",
)

#: The running sums the runner accumulates for the agent (the other columns follow from them).
AGENT_COLUMNS = ("cumulative_regret", "cumulative_reward", "cumulative_expected_reward", "normalized_cumulative_regret")


def _check_variant(variant: str) -> None:
    check_variant(variant)


class IndicatorConstants(struct.PyTreeNode):
    """Per-MDP constants of the indicators.

    ``optimal``, ``worst``, ``random``: per-step expected reward of the optimal, worst and uniformly random policies
    (continuous: gains from ``P0``; episodic: ``sum_s P0(s) V_0(s) / H``). ``optimal_start_values`` and
    ``worst_start_values``: ``V*_0`` and ``V^-_0`` of every state (episodic; gains of those policies when continuous).
    ``state_order``: the MDP's :func:`jaxmdp.gth.band_order` for the banded exact gain of :func:`policy_values`
    (continuous; the runner sets it on a CPU), or ``None``.
    """

    optimal: jax.Array
    worst: jax.Array
    random: jax.Array
    optimal_start_values: jax.Array
    worst_start_values: jax.Array
    state_order: jax.Array | None = None


class Instant(struct.PyTreeNode):
    """Indicators of one policy at one log: per-step expected ``regret``, ``normalized_regret`` and
    ``expected_reward``."""

    regret: jax.Array
    normalized_regret: jax.Array
    expected_reward: jax.Array


def indicator_constants(mdp: MDP, variant: Variant = "paper") -> IndicatorConstants:
    """The constants of :class:`IndicatorConstants` for one (unbatched) MDP; jittable, ``variant`` static."""
    check_variant(variant)
    ref = reference_values(mdp, variant)
    if mdp.episodic:
        horizon = mdp.horizon.astype(mdp.dtype)
        per_step = lambda v: v / horizon  # noqa: E731
        return IndicatorConstants(
            optimal=per_step(ref.optimal),
            worst=per_step(ref.worst),
            random=per_step(ref.random),
            optimal_start_values=ref.optimal_state_values,
            worst_start_values=ref.worst_state_values,
        )
    return IndicatorConstants(
        optimal=ref.optimal,
        worst=ref.worst,
        random=ref.random,
        optimal_start_values=ref.optimal_state_values,
        worst_start_values=ref.worst_state_values,
    )


def _safe_ratio(num: jax.Array, den: jax.Array, scale: jax.Array) -> jax.Array:
    degenerate = den <= _DEGENERATE_RTOL * (1.0 + jnp.abs(scale))
    return jnp.where(degenerate, 0.0, num / jnp.where(degenerate, 1.0, den))


#: Sweeps over the successor lists that :func:`policy_values` spends trying to certify a gain before it falls back
#: to the dense solve: near-optimal policies of the benchmark's MDPs certify within 32 to 128 sweeps, which cost a
#: fraction of the dense solve, and most policies that the runner evaluates certify (the exceptions are slowly
#: mixing chains, as on FrozenLake; docs/performance.md, Continuous indicators).
ITERATIVE_GAIN_SWEEPS = 128
#: The runner's ``give_up`` for :func:`~jaxmdp.dynamic_programming.successor_gain_bounds`: the bounds stop once, at
#: their rate of contraction, certifying would take more than 16 times the sweeps left. On the benchmark's
#: continuous MDPs most chains that would not certify within :data:`ITERATIVE_GAIN_SWEEPS` stop early, and nearly all
#: that certify still do, with the same bounds (docs/performance.md, Continuous indicators).
ITERATIVE_GAIN_GIVE_UP = 16.0


def policy_values(
    mdp: MDP,
    policy: jax.Array,
    iterative_sweeps: int = 0,
    rows: jax.Array | None = None,
    member: jax.Array | None = None,
    order: jax.Array | None = None,
    bandwidth: int | None = None,
    check_band: bool = True,
    give_up: float | None = None,
) -> jax.Array:
    """The expensive half of an indicator: ``V^pi_0(s)`` for every state (episodic, finite-horizon evaluation on the
    successor lists) or the gain ``rho^pi(s)`` from every state (continuous), ``[S]``.

    Continuous: with ``iterative_sweeps > 0`` (static), :func:`~jaxmdp.dynamic_programming.successor_gain_bounds`
    first tries to certify the gain to a relative ``1e-6`` within that many sweeps over the successor lists
    (``O(S A K)`` each, ``O(S K)`` for action indices; with ``give_up``, e.g. the runner's
    :data:`ITERATIVE_GAIN_GIVE_UP`, stopping early where at their rate of contraction they would not) and returns
    the midpoint of its bounds; otherwise, or when the chain mixes too slowly for that, the dense ``O(S^3)``
    :func:`~jaxmdp.dynamic_programming.gain_vector`. The branch is a ``lax.cond``, so use it per member
    (``lax.map``), not under ``vmap``.

    ``policy`` may also be a deterministic policy given by its action indices (an integer ``[H, S]`` or ``[S]``
    array, an agent's ``greedy_actions``): episodic, only the chosen actions' successor lists are read
    (:func:`~jaxmdp.dynamic_programming.finite_horizon_deterministic_start_values`, the same numbers as its one-hot
    policy); continuous, the certified bounds sweep the chosen actions' successor slots only (``K`` a state instead
    of ``A K``) and the dense fallback takes its one-hot policy. ``rows`` and ``member`` (episodic action indices
    only, else ignored): a stacked MDP's :func:`~jaxmdp.dynamic_programming.successor_rows` and this MDP's index in
    it, read instead of the MDP's own rows (see that function). ``order`` and ``bandwidth`` (static): the MDP's
    :func:`jaxmdp.gth.band_order`, for the banded elimination of the dense fallback (continuous; ``O(S w^2)``), and
    ``check_band`` (static) as in :func:`~jaxmdp.dynamic_programming.gain_vector`: False where ``order`` is the
    MDP's own band order."""
    integer = jnp.issubdtype(policy.dtype, jnp.integer)
    if integer and mdp.episodic:
        actions = policy if policy.ndim == 2 else jnp.broadcast_to(policy, (mdp.H, *policy.shape))
        return dp.finite_horizon_deterministic_start_values(mdp, actions, rows, None if rows is None else member)
    if mdp.episodic:
        return dp.finite_horizon_start_values(mdp, policy)

    def dense() -> jax.Array:
        pi = jax.nn.one_hot(policy, mdp.n_actions, dtype=mdp.R.dtype) if integer else policy
        return dp.gain_vector(mdp, pi, order=order, bandwidth=bandwidth, check_band=check_band)

    if iterative_sweeps <= 0:
        return dense()
    # Action indices go to the bounds as they are: sweeps over the chosen actions' K slots only.
    bounds = dp.successor_gain_bounds(mdp, policy, max_sweeps=iterative_sweeps, give_up=give_up)
    return jax.lax.cond(bounds.certified, lambda: 0.5 * (bounds.lower + bounds.upper), dense)


def instant_from_values(
    mdp: MDP,
    consts: IndicatorConstants,
    values: jax.Array,
    state: jax.Array,
    episode_start: jax.Array,
    variant: Variant = "paper",
) -> Instant:
    """The cheap half: the indicators of a policy whose :func:`policy_values` are ``values`` (module docstring)."""
    check_variant(variant)
    if mdp.episodic:
        horizon = mdp.horizon.astype(mdp.dtype)
        if variant == "paper":
            gap = jnp.maximum(mdp.P0 @ (consts.optimal_start_values - values), 0.0)
            span = mdp.P0 @ (consts.optimal_start_values - consts.worst_start_values)
            scale = mdp.P0 @ consts.optimal_start_values
        else:
            gap = jnp.maximum(consts.optimal_start_values[episode_start] - values[episode_start], 0.0)
            span = consts.optimal_start_values[episode_start] - consts.worst_start_values[episode_start]
            scale = consts.optimal_start_values[episode_start]
        return Instant(
            regret=gap / horizon,
            normalized_regret=_safe_ratio(gap, span, scale),
            expected_reward=(mdp.P0 @ values) / horizon,
        )
    rho = values[state]
    regret = jnp.maximum(consts.optimal - rho, 0.0)
    if variant == "colosseum":
        regret = jnp.where(regret <= COLOSSEUM_REGRET_ATOL, 0.0, regret)
    return Instant(
        regret=regret,
        normalized_regret=_safe_ratio(regret, consts.optimal - consts.worst, consts.optimal),
        expected_reward=rho,
    )


def instantaneous(
    mdp: MDP,
    consts: IndicatorConstants,
    policy: jax.Array,
    state: jax.Array,
    episode_start: jax.Array,
    variant: Variant = "paper",
) -> Instant:
    """Exact per-step expected regret, normalised regret and expected reward of ``policy`` (module docstring).

    Args:
      mdp: one (unbatched) MDP.
      consts: its :func:`indicator_constants` (same ``variant``).
      policy: ``[S, A]`` (continuous, stationary) or ``[H, S, A]`` / ``[S, A]`` (episodic) action probabilities.
      state: the MDP's current state (used by continuous MDPs: the gain of a multichain policy depends on it).
      episode_start: start state of the most recent episode (used by the colosseum episodic variant).
      variant: ``"paper"`` (default) or ``"colosseum"``.
    """
    return instant_from_values(mdp, consts, policy_values(mdp, policy), state, episode_start, variant)


def baseline_columns(
    steps: np.ndarray, optimal: np.ndarray, worst: np.ndarray, random: np.ndarray
) -> dict[str, np.ndarray]:
    """The random / worst / optimal baseline columns of docs/measures.md §6.3 after ``steps`` steps (host-side numpy).

    With per-step expected rewards ``rho*``, ``rho^-``, ``rho^u`` and ``c = steps``: the random policy's cumulative
    regret is ``(rho* - rho^u) c``, its normalised one ``(rho* - rho^u) / (rho* - rho^-) c``, its cumulative expected
    reward ``rho^u c`` and the normalised one ``(rho^u - rho^-) / (rho* - rho^-) c``; likewise for the worst and
    optimal policies. Arguments broadcast against each other.
    """
    c = np.asarray(steps, np.float64)
    opt, wst, rnd = (np.asarray(x, np.float64) for x in (optimal, worst, random))
    span = opt - wst
    degenerate = span <= _DEGENERATE_RTOL * (1.0 + np.abs(opt))
    inv = np.where(degenerate, 0.0, 1.0 / np.where(degenerate, 1.0, span))
    return {
        "random_cumulative_regret": (opt - rnd) * c,
        "random_cumulative_expected_reward": rnd * c,
        "random_normalized_cumulative_regret": (opt - rnd) * inv * c,
        "random_normalized_cumulative_expected_reward": (rnd - wst) * inv * c,
        "worst_cumulative_regret": span * c,
        "worst_cumulative_expected_reward": wst * c,
        "worst_normalized_cumulative_regret": np.where(degenerate, 0.0, 1.0) * c,
        "worst_normalized_cumulative_expected_reward": np.zeros_like(span * c),
        "optimal_cumulative_expected_reward": opt * c,
        "optimal_normalized_cumulative_expected_reward": np.where(degenerate, 0.0, 1.0) * c,
    }


def normalized_reward(cumulative: np.ndarray, steps: np.ndarray, optimal: np.ndarray, worst: np.ndarray) -> np.ndarray:
    """``(C - c rho^-) / (rho* - rho^-)``: a cumulative (expected) reward ``C`` after ``c`` steps, normalised
    (docs/measures.md §6.3; 0 when the normaliser vanishes)."""
    c = np.asarray(steps, np.float64)
    opt, wst = np.asarray(optimal, np.float64), np.asarray(worst, np.float64)
    span = opt - wst
    degenerate = span <= _DEGENERATE_RTOL * (1.0 + np.abs(opt))
    return np.where(degenerate, 0.0, (np.asarray(cumulative, np.float64) - c * wst) / np.where(degenerate, 1.0, span))
