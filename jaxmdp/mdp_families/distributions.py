"""Reward distributions of the families: Beta or point mass (docs/families.md §1.5).

A family's reward distribution ``D(s, a, s')`` is stored in the MDP as its mean and Beta concentration
(``conc = alpha + beta``, ``0`` for a point mass). Users may pass distributions as :class:`Beta` / :class:`PointMass`
objects or as Colosseum-style tuples ``("beta", (a, b))`` / ``("deterministic", (c,))``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

__all__ = [
    "Beta",
    "PointMass",
    "Distribution",
    "beta_with_mean",
    "as_distribution",
    "resolve_distributions",
    "check_default_reward_parameter",
    "check_reward_margin",
    "RewardParameters",
    "RewardArguments",
]


@dataclasses.dataclass(frozen=True)
class Beta:
    """Beta(a, b) reward on [0, 1]; mean ``a / (a + b)``."""

    a: float
    b: float

    def __post_init__(self) -> None:
        if not (self.a > 0 and self.b > 0):
            raise ValueError(f"Beta parameters must be positive; got a={self.a}, b={self.b}")

    @property
    def mean(self) -> float:
        return self.a / (self.a + self.b)

    @property
    def conc(self) -> float:
        return self.a + self.b

    def __str__(self) -> str:
        return f"Beta({self.a:g}, {self.b:g})"


@dataclasses.dataclass(frozen=True)
class PointMass:
    """Deterministic reward ``value`` (Colosseum's ``deterministic`` distribution)."""

    value: float

    @property
    def mean(self) -> float:
        return self.value

    @property
    def conc(self) -> float:
        return 0.0

    def __str__(self) -> str:
        return f"Deterministic({self.value:g})"


Distribution = Beta | PointMass


def beta_with_mean(v: float, mu: float, scale: float = 1) -> Beta:
    """``Beta(v, v (scale / mu - 1))``: the family defaults' Beta of mean ``mu / scale`` with first parameter ``v``
    (the variance multiplier; ``a + b = v scale / mu``). Proper exactly when ``0 < mu < scale``, which the families
    check first (:func:`check_default_reward_parameter`)."""
    return Beta(v, v * (scale / mu - 1))


def as_distribution(name: str, spec: Any) -> Distribution:
    """Parse a user-given distribution for parameter ``name``."""
    if isinstance(spec, (Beta, PointMass)):
        return spec
    if isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[0], str):
        kind, args = spec[0].lower(), tuple(spec[1])
        if kind == "beta" and len(args) == 2:
            return Beta(float(args[0]), float(args[1]))
        if kind in ("deterministic", "point", "pointmass") and len(args) == 1:
            return PointMass(float(args[0]))
    raise ValueError(
        f"{name} must be a Beta / PointMass, ('beta', (a, b)) or ('deterministic', (c,)); got {spec!r}"
    )


def resolve_distributions(
    given: Mapping[str, Any],
    defaults: Callable[[], Mapping[str, Distribution]],
    make_reward_stochastic: bool,
) -> dict[str, Distribution]:
    """Explicit distributions (all or none, matching ``make_reward_stochastic``) or the family defaults, keyed in the
    order of ``given`` (the family's parameter order).

    ``defaults()`` builds the family's default distributions for ``make_reward_stochastic``; it is called only when
    no distribution is given, so it is where the parameters that only the defaults depend on are validated (with
    :func:`check_default_reward_parameter`).
    """
    provided = {k: v for k, v in given.items() if v is not None}
    if not provided:
        chosen = defaults()
        return {k: chosen[k] for k in given}
    if len(provided) != len(given):
        missing = sorted(set(given) - set(provided))
        raise ValueError(f"reward distributions must be given all or none; missing {missing}")
    dists = {k: as_distribution(k, v) for k, v in provided.items()}
    for k, d in dists.items():
        if make_reward_stochastic and isinstance(d, PointMass):
            raise ValueError(f"{k} is a point mass but make_reward_stochastic=True")
        if not make_reward_stochastic and not isinstance(d, PointMass):
            raise ValueError(f"{k} is stochastic but make_reward_stochastic=False")
    return dists


def check_default_reward_parameter(name: str, value: float, upper: float, upper_text: str | None = None) -> None:
    """Raise ``ValueError`` unless ``0 < value < upper``: the range in which the family's stochastic default rewards
    have positive Beta parameters. ``upper_text`` is how the message writes ``upper`` (e.g. ``"size=4"``)."""
    if not 0 < value < upper:
        bound = f"{upper:g}" if upper_text is None else upper_text
        raise ValueError(f"{name} must lie in (0, {bound}) for the stochastic default rewards; got {value}")


def check_reward_margin(optimal_name: str, optimal: float, sub_optimal_name: str, sub_optimal: float) -> None:
    """Raise ``ValueError`` unless ``optimal - 0.1 > sub_optimal``: the family's optimal reward (or return) clearly
    above its sub-optimal one, as the reference requires (docs/families.md)."""
    if not optimal - 0.1 > sub_optimal:
        raise ValueError(
            f"{optimal_name} - 0.1 must exceed {sub_optimal_name}; got {optimal_name}={optimal}, "
            f"{sub_optimal_name}={sub_optimal}"
        )


@dataclasses.dataclass(frozen=True)
class RewardArguments:
    """The reward arguments of one builder call, as given: ``make_reward_stochastic`` and
    ``reward_variance_multiplier`` (validated by :class:`~jaxmdp.mdp_families.CommonParams`), and the family's own
    mean parameters and explicit distributions by name (validated by
    :meth:`~jaxmdp.mdp_families.Family.set_rewards`)."""

    stochastic: bool
    variance_multiplier: float
    means: Mapping[str, Any]
    distributions: Mapping[str, Any]


@dataclasses.dataclass(frozen=True)
class RewardParameters:
    """The reward parameters of a family, one specification that every family shares (docs/families.md §1.5).

    ``distributions``: the names of the explicit reward distributions, in the family's parameter order (the order of
    ``MDPInfo.params``); they are given all or none, and the family's
    :meth:`~jaxmdp.mdp_families.Family.default_rewards` supplies them otherwise. ``means``: the names of the
    ``(optimal, sub-optimal)`` mean rewards or returns that the stochastic defaults are built from, or none.
    ``check_margin``: whether the means must satisfy ``optimal - 0.1 > sub_optimal`` (:func:`check_reward_margin`;
    False for a family that checks a margin of its own). The builder's declaration names every one of these
    parameters and holds their defaults (:func:`~jaxmdp.mdp_families.construction.family_builder`).
    """

    distributions: tuple[str, ...]
    means: tuple[str, ...] = ()
    check_margin: bool = True

    def __post_init__(self) -> None:
        if self.means and len(self.means) != 2:
            raise ValueError(f"means names the optimal and the sub-optimal mean parameter; got {self.means}")

    @property
    def names(self) -> tuple[str, ...]:
        """Every parameter of the specification: the means, then the distributions."""
        return self.means + self.distributions

    def arguments(self, values: Mapping[str, Any], stochastic: bool, variance_multiplier: float) -> RewardArguments:
        """The :class:`RewardArguments` of a call whose arguments by name are ``values``."""
        return RewardArguments(
            stochastic=stochastic,
            variance_multiplier=variance_multiplier,
            means={name: values[name] for name in self.means},
            distributions={name: values[name] for name in self.distributions},
        )
