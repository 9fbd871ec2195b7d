"""Host-side construction of a family's MDP, reproducing Colosseum's state order and random draws.

A family describes its dynamics on *nodes* (small immutable records) through :class:`Family`; :func:`build_mdp`
turns it into an :class:`~jaxmdp.MDP` exactly as docs/families.md §1 states:

1. two generators from ``seed``: ``G = numpy.random.RandomState(seed)`` and ``F = random.Random(seed)``;
2. the family's starting nodes (drawing from ``G`` / ``F`` as the family specifies);
3. a depth-first expansion from the starting nodes (§1.6): for each base action ``b`` of a node, the effective
   outcome list of ``b`` (§1.3: own outcomes, lazy self-loop, other actions' outcomes) is appended to the discovery
   list, and unvisited next nodes are expanded immediately. State index = discovery position. The action
   permutation ``sigma_n = argsort(G.rand(A))`` (``randomize_actions``) is drawn when ``n`` is first processed if
   the rewards are point masses, but only *after* the subtree reached through base action 0 of ``n`` has been
   expanded if they are stochastic (except for the very first node) -- the reference draws it lazily and its
   first use depends on its "all rewards deterministic" flag (this refines docs/families.md §1.4/§1.6, which state the
   pre-order draw only);
4. ``T[s, sigma_n[b], s'] += p`` for every entry, and ``reward_mean/conc[s, sigma_n[b], s'] = D(n, b, n')``, filled for
   every ``s'`` a kernel transform could add (``s`` itself and every action's successors);
5. the horizon (§1.8): ``max(H_min, H)`` with ``H_min = 1 + max eccentricity of the possible starting nodes`` unless
   the family overrides it (the eccentricity search then does not run).

The draws from ``F`` made while expanding (the seeds of the reference's per-pair samplers) influence nothing
structural and are skipped. Agent action ``k`` executes base action ``sigma_n^{-1}[k]`` and is rewarded with that
base action's distribution (the reference looks the reward up with ``sigma_n[k]``, docs/families.md §1.4 [quirk]; the
two agree in every shipped family because their action-dependent rewards have ``A = 2`` or no randomisation).
"""

from __future__ import annotations

import abc
import functools
import inspect
import random
from collections.abc import Callable, Hashable, Iterator, Sequence
from typing import Any

import numpy as np

from jaxmdp._checks import check_bool, check_int
from jaxmdp._memory import check_memory
from jaxmdp.mdp import MDP, MDPInfo, custom_dense_bytes, custom_mdp, mdp_array_bytes
from jaxmdp.mdp_families.distributions import (
    Distribution,
    PointMass,
    RewardArguments,
    RewardParameters,
    check_reward_margin,
    resolve_distributions,
)
from jaxmdp.transforms import MAX_NOISE_PROBABILITY

__all__ = [
    "Family",
    "CommonParams",
    "COMMON_PARAMETERS",
    "COMMON_DEFAULTS",
    "build_mdp",
    "family_builder",
    "check_noise_probability",
    "integer_parameter",
    "construction_bytes",
]

Node = Hashable


#: Item size of the dtype a family's MDP is built in (:func:`~jaxmdp.custom_mdp`'s default, float32).
_BUILD_ITEMSIZE = 4
#: Bytes a family's expansion holds in Python objects per state and action, besides the arrays: the node records and
#: their discovery index, the outcome lists of every base action, the action permutations, the labels, node values and
#: successor orders of the MDPInfo (the built-in families hold about 700, traced with tracemalloc; three times that).
PYTHON_BYTES_PER_STATE_ACTION = 2048


def construction_bytes(S: int, A: int) -> int:
    """Peak bytes of :func:`build_mdp` for at most ``S`` states and ``A`` actions: its three float64 ``[S, A, S]``
    arrays and :func:`~jaxmdp.custom_mdp`'s work on them (:func:`~jaxmdp.mdp.custom_dense_bytes`, which counts those
    three arrays), the successor lists of one successor per row, and the Python objects of the expansion."""
    return (
        custom_dense_bytes(S, A, _BUILD_ITEMSIZE)
        + S * A * (12 + 2 * _BUILD_ITEMSIZE)
        + PYTHON_BYTES_PER_STATE_ACTION * S * A
    )


def integer_parameter(name: str, value: Any, minimum: int, family: str, maximum: int | None = None) -> int:
    """``value`` as an ``int`` after checking ``minimum <= value (<= maximum)``; the ``ValueError`` names ``name``,
    ``family`` and the allowed range (:func:`jaxmdp._checks.check_int`)."""
    return check_int(name, value, minimum, maximum, context=f" for {family}")


def check_noise_probability(name: str, value: float | None) -> float:
    """Validate ``p_rand`` / ``p_lazy``: ``None`` or a number in ``[0, 0.9999)``; returns it as a float."""
    if value is None:
        return 0.0
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number in [0, {MAX_NOISE_PROBABILITY}) or None; got {value!r}") from None
    if not (0.0 <= v < MAX_NOISE_PROBABILITY):
        raise ValueError(f"{name} must lie in [0, {MAX_NOISE_PROBABILITY}); got {v}")
    return v


#: Keyword parameters that every family builder takes (docs/families.md §1.2), validated by :class:`CommonParams`.
COMMON_PARAMETERS = (
    "episodic",
    "seed",
    "p_rand",
    "p_lazy",
    "randomize_actions",
    "make_reward_stochastic",
    "reward_variance_multiplier",
    "H",
)

#: The defaults of the common parameters (``episodic`` and ``seed`` have none). Every builder declares them in its
#: public signature; :func:`family_builder` checks that the declaration agrees with this table.
COMMON_DEFAULTS: dict[str, Any] = {
    "p_rand": None,
    "p_lazy": None,
    "randomize_actions": True,
    "make_reward_stochastic": False,
    "reward_variance_multiplier": 1.0,
    "H": None,
}


class CommonParams:
    """Validated parameters shared by every family (docs/families.md §1.2)."""

    def __init__(
        self,
        *,
        episodic: bool,
        seed: int,
        p_rand: float | None,
        p_lazy: float | None,
        randomize_actions: bool,
        make_reward_stochastic: bool,
        reward_variance_multiplier: float,
        H: int | None,
    ) -> None:
        check_bool("episodic", episodic)
        check_int("seed", seed, 0)
        if not (isinstance(reward_variance_multiplier, (int, float)) and reward_variance_multiplier > 0):
            raise ValueError(f"reward_variance_multiplier must be > 0; got {reward_variance_multiplier!r}")
        if H is not None:
            if not episodic:
                raise ValueError("H is only meaningful for episodic MDPs (episodic=True)")
            check_int("H", H, context=" or None")
        self.episodic = bool(episodic)
        self.seed = int(seed)
        self.p_rand = check_noise_probability("p_rand", p_rand)
        self.p_lazy = check_noise_probability("p_lazy", p_lazy)
        self.randomize_actions = bool(randomize_actions)
        self.make_reward_stochastic = bool(make_reward_stochastic)
        self.reward_variance_multiplier = float(reward_variance_multiplier)
        self.H = None if H is None else int(H)

    def as_params(self) -> tuple[tuple[str, Any], ...]:
        """The common part of the parameter dictionary, in the reference's order (§1.11)."""
        return (
            ("seed", self.seed),
            ("randomize_actions", self.randomize_actions),
            ("p_lazy", self.p_lazy or None),
            ("p_rand", self.p_rand or None),
            ("make_reward_stochastic", self.make_reward_stochastic),
            ("reward_variance_multiplier", self.reward_variance_multiplier),
        )


class Family(abc.ABC):
    """A family's dynamics on nodes. Subclasses set ``name``, ``n_actions``, ``node_fields`` and implement the
    abstract methods; :func:`build_mdp` does the rest. The constructor takes every parameter without a default: the
    defaults live in one place, the builder's declaration (:func:`family_builder`), which passes them all.

    A family with ``reward_parameters`` (every built-in one) receives its reward parameters as one
    :class:`~jaxmdp.mdp_families.distributions.RewardArguments` (``rewards``), validates them with
    :meth:`set_rewards` and supplies its default distributions with :meth:`default_rewards`."""

    name: str = ""
    n_actions: int = 0
    node_fields: tuple[str, ...] = ()
    #: False for a family that never relabels its actions (its builder forces ``randomize_actions=False``).
    randomize_actions_allowed: bool = True
    #: False for a family without a lazy mechanic (its builder rejects a positive ``p_lazy``).
    lazy_allowed: bool = True
    #: The family's reward parameters; None for a family whose constructor takes and resolves them itself.
    reward_parameters: RewardParameters | None = None
    #: The reward distributions by parameter name (set by :meth:`set_rewards`).
    dists: dict[str, Distribution]

    def default_rewards(self, stochastic: bool, v: float) -> tuple[Distribution, ...]:
        """The default distributions, in the order of ``reward_parameters.distributions``: point masses, or Betas
        with variance multiplier ``v`` when ``stochastic``. Called only when no distribution is given, so it is where
        the parameters that only the defaults depend on are validated (with
        :func:`~jaxmdp.mdp_families.distributions.check_default_reward_parameter`)."""
        raise NotImplementedError(f"{type(self).__name__} declares reward_parameters but no default_rewards")

    def set_rewards(self, rewards: RewardArguments) -> None:
        """Validate the reward arguments and set them: the means (``optimal - 0.1 > sub_optimal`` where
        ``reward_parameters.check_margin``) as float attributes of their names, and ``dists``, the explicit
        distributions (all or none, matching ``make_reward_stochastic``) or :meth:`default_rewards`."""
        spec = self.reward_parameters
        if spec.check_margin and rewards.means:
            (optimal_name, optimal), (sub_optimal_name, sub_optimal) = rewards.means.items()
            check_reward_margin(optimal_name, optimal, sub_optimal_name, sub_optimal)
        for name, value in rewards.means.items():
            setattr(self, name, float(value))

        def defaults() -> dict[str, Distribution]:
            return dict(zip(spec.distributions, self.default_rewards(rewards.stochastic, rewards.variance_multiplier)))

        self.dists = resolve_distributions(rewards.distributions, defaults, rewards.stochastic)

    def distribution_params(self) -> tuple[tuple[str, str], ...]:
        """The distributions' entries of :meth:`params`: ``(name, str(distribution))`` in parameter order."""
        return tuple((k, str(d)) for k, d in self.dists.items())

    @abc.abstractmethod
    def outcomes(self, node: Node, action: int) -> Sequence[tuple[Node, float]]:
        """Base outcome list ``[(next_node, probability), ...]`` of base action ``action`` (duplicates allowed)."""

    @abc.abstractmethod
    def reward(self, node: Node, action: int, next_node: Node) -> Distribution:
        """Reward distribution ``D(node, action, next_node)`` of base action ``action``."""

    @abc.abstractmethod
    def starting_nodes(
        self, G: np.random.RandomState, F: random.Random
    ) -> tuple[list[Node], list[float], list[Node]]:
        """``(starting nodes, their probabilities, possible starting nodes)``, drawing from ``G`` / ``F``."""

    def params(self) -> tuple[tuple[str, Any], ...]:
        """The family's own parameters in the reference's order (docs/families.md, each family's 'parameter dict')."""
        return ()

    def minimum_horizon(self, eccentricity: Callable[[], int]) -> int:
        """``H_min`` of the episodic version; ``eccentricity()`` searches the graph for the largest shortest-path
        distance from a possible starting node (default: ``1 + eccentricity()``, docs/families.md §1.8). A family whose
        horizon does not depend on the graph should not call it."""
        return 1 + eccentricity()

    def fixed_horizon(self) -> int | None:
        """A horizon that the family imposes (and that the user may not set), or None."""
        return None

    def max_states(self) -> int | None:
        """An upper bound on the number of states, from the parameters alone and without building anything (no node
        is expanded): what :meth:`check_memory` sizes the dense arrays with. ``None`` (the default) when the family
        knows none; its MDP is then checked by :func:`~jaxmdp.custom_mdp` only, once the expansion has found ``S``."""
        return None

    def size_parameters(self) -> dict[str, Any]:
        """The parameters :meth:`max_states` is computed from, by name (named by a refusal)."""
        return {}

    def extra_bytes(self) -> int:
        """Bytes the family's own set-up holds besides the MDP's arrays (a layout drawn in batches, ...); 0 unless a
        family says otherwise."""
        return 0

    def check_memory(self) -> None:
        """Raise :class:`~jaxmdp.NotEnoughMemory` (a ``ValueError``) naming the size parameters if the MDP of
        at most :meth:`max_states` states cannot be built in the memory available (:func:`construction_bytes`).

        A family calls it in its constructor as soon as its size parameters are validated, before it draws or builds
        anything that grows with them; :func:`build_mdp` calls it again before expanding the nodes."""
        S = self.max_states()
        if S is None:
            return
        need = construction_bytes(int(S), self.n_actions) + int(self.extra_bytes())
        names = list(self.size_parameters())
        check_memory(
            need,
            f"the {self.name} MDP",
            self.size_parameters(),
            detail=f"at most {int(S)} states, {self.n_actions} actions",
            device_bytes=mdp_array_bytes(int(S), self.n_actions, 1, _BUILD_ITEMSIZE),
            remedy=f"use a smaller {' / '.join(names) if names else 'MDP'}, or a machine with more memory",
        )

    def node_values(self, node: Node) -> tuple[int, ...]:
        """The node's fields as integers (the ``StateInfo`` vector)."""
        return tuple(int(v) for v in node)

    def node_label(self, node: Node) -> str:
        """``"X=0,Y=2"``-style label (Colosseum's ``str(node)``)."""
        return ",".join(f"{f}={v}" for f, v in zip(self.node_fields, node))

    def layout(self) -> tuple[tuple[str, Any], ...]:
        """Static, hashable data needed to render states (walls, goal, ...)."""
        return ()


def _effective_outcomes(
    base: Sequence[Sequence[tuple[Node, float]]], node: Node, b: int, p_rand: float, p_lazy: float
) -> list[tuple[Node, float]]:
    """docs/families.md §1.3: own outcomes, then the lazy self-loop, then the other actions' outcomes (``base[c]`` is
    the base outcome list of action ``c`` at ``node``)."""
    A = len(base)
    own_w = (1.0 - p_lazy) * ((1.0 - p_rand) + p_rand / A)
    out = [(n2, q * own_w) for n2, q in base[b]]
    if p_lazy > 0:
        out.append((node, p_lazy))
    if p_rand > 0:
        other_w = (1.0 - p_lazy) * p_rand / A
        for c in range(A):
            if c != b:
                out.extend((n2, q * other_w) for n2, q in base[c])
    return out


def _eccentricity(successors: Callable[[Node], Sequence[Node]], sources: Sequence[Node]) -> int:
    """Largest shortest-path distance from any source (§1.8).

    One breadth-first search serves all the sources: each node carries the set of sources that have reached it as the
    bits of a Python integer, and a level adds to a node the sources that reach it first at that distance. The last
    level that adds anything is the largest distance of all.
    """
    reached: dict[Node, int] = {}
    for i, src in enumerate(sources):
        reached[src] = reached.get(src, 0) | (1 << i)
    frontier = dict(reached)
    depth = 0
    while True:
        new: dict[Node, int] = {}
        for n, bits in frontier.items():
            for n2 in successors(n):
                fresh = bits & ~reached.get(n2, 0)
                if fresh:
                    new[n2] = new.get(n2, 0) | fresh
        if not new:
            return depth
        for n2, bits in new.items():
            reached[n2] = reached.get(n2, 0) | bits
        frontier = new
        depth += 1


def build_mdp(fam: Family, common: CommonParams) -> MDP:
    """Build the :class:`~jaxmdp.MDP` of family ``fam`` with the common parameters (see the module docstring)."""
    fam.check_memory()
    A = fam.n_actions
    G = np.random.RandomState(common.seed)
    F = random.Random(common.seed)
    starts, start_probs, possible_starts = fam.starting_nodes(G, F)
    randomize = common.randomize_actions and fam.randomize_actions_allowed
    r, l = common.p_rand, common.p_lazy  # noqa: E741

    base: dict[Node, list[Sequence[tuple[Node, float]]]] = {}

    def outcomes(n: Node) -> list[Sequence[tuple[Node, float]]]:
        # Every base action's outcome list, asked of the family once per node (the effective lists, the reward
        # neighbourhood and the eccentricity search all reuse it).
        if n not in base:
            base[n] = [fam.outcomes(n, c) for c in range(A)]
        return base[n]

    index: dict[Node, int] = {}
    sigma: dict[Node, np.ndarray] = {}
    lists: dict[tuple[Node, int], list[tuple[Node, float]]] = {}  # keyed by (node, base action)
    visited: set[Node] = set()

    def discover(n: Node) -> None:
        if n not in index:
            index[n] = len(index)

    def draw_sigma(n: Node) -> None:
        if n not in sigma:
            sigma[n] = np.argsort(G.rand(A)) if randomize else np.arange(A)

    # The reference draws sigma_n lazily, the first time it needs it: either when it looks up a reward distribution
    # of n to update its "all rewards deterministic" flag (done for every outcome entry while the flag is still
    # True), or when it files the outcome list of base action 0 under its agent label, which happens only *after*
    # the recursion into that list's next nodes. With point-mass rewards the first case always fires, so sigma_n is
    # drawn when n is first processed (pre-order). With stochastic rewards the flag turns False at the very first
    # lookup (the first starting node), and every other sigma_n is drawn after the subtree reached through base
    # action 0 of n has been expanded (post-order). Verified on the stochastic ref02 (RiverSwim), ref11 (DeepSea)
    # and ref20 (SimpleGrid), and on the point-mass ref30 (MiniGridEmpty, checked with a throwaway family).
    rewards_deterministic = [True]

    def expand(n: Node) -> Iterator[Node]:
        # One frame of the reference's recursive visit; yields each child to expand before continuing.
        for b in range(A):
            lst = _effective_outcomes(outcomes(n), n, b, r, l)
            discover(n)
            for n2, _ in lst:
                discover(n2)
                if rewards_deterministic[0]:
                    draw_sigma(n)
                    # The reference's lookup uses sigma_n[b] as the base action (docs/families.md §1.4 [quirk]).
                    if not isinstance(fam.reward(n, int(sigma[n][b]), n2), PointMass):
                        rewards_deterministic[0] = False
            visited.add(n)
            lists[(n, b)] = lst
            for n2, _ in lst:
                if n2 not in visited:
                    yield n2
            draw_sigma(n)

    for s0 in starts:
        if s0 in visited:
            continue
        stack = [expand(s0)]
        while stack:
            child = next(stack[-1], None)
            if child is None:
                stack.pop()
            elif child not in visited:
                stack.append(expand(child))

    nodes = list(index)
    S = len(nodes)
    T = np.zeros((S, A, S))
    reward_mean = np.zeros((S, A, S))
    reward_conc = np.zeros((S, A, S))
    for n in nodes:
        s = index[n]
        neighbours = {n}
        for lst in outcomes(n):
            neighbours.update(n2 for n2, _ in lst)
        for b in range(A):
            k = int(sigma[n][b])
            for n2, p in lists[(n, b)]:
                T[s, k, index[n2]] += p
            for n2 in neighbours:
                d = fam.reward(n, b, n2)
                reward_mean[s, k, index[n2]] = d.mean
                reward_conc[s, k, index[n2]] = d.conc

    P0 = np.zeros(S)
    for n, p in zip(starts, start_probs):
        P0[index[n]] += p

    H = None
    if common.episodic:
        fixed = fam.fixed_horizon()
        if fixed is not None:
            if common.H is not None:
                raise ValueError(f"{fam.name} fixes its horizon to {fixed}; H must not be given")
            H = fixed
        else:
            def successors(n: Node) -> list[Node]:
                return [n2 for lst in outcomes(n) for n2, q in lst if q > 0]

            H_min = fam.minimum_horizon(lambda: _eccentricity(successors, possible_starts))
            H = H_min if common.H is None else max(H_min, common.H)

    # The reference's episodic graph (docs/families.md §1.8) walks each node's successors in edge-creation order and the
    # starts in sampler order; record both so jaxmdp.episodic can reproduce its pair order (and its reset quirk).
    successor_order = tuple(
        tuple(dict.fromkeys(index[n2] for b in range(A) for n2, p in lists[(n, b)] if p > 0)) for n in nodes
    )
    start_order = tuple(dict.fromkeys(index[n] for n, p in zip(starts, start_probs) if p > 0))
    info = MDPInfo(
        family=fam.name,
        params=common.as_params() + fam.params() + ((("H", H),) if H is not None else ()),
        node_labels=tuple(fam.node_label(n) for n in nodes),
        node_fields=fam.node_fields,
        node_values=tuple(fam.node_values(n) for n in nodes),
        layout=fam.layout() + (("successor_order", successor_order), ("start_order", start_order)),
    )
    return custom_mdp(T, P0=P0, H=H, reward_mean=reward_mean, reward_conc=reward_conc, info=info)


def family_builder(family: type[Family]) -> Callable[[Callable[..., MDP]], Callable[..., MDP]]:
    """Decorator making a signature-only function the builder of ``family``.

    The decorated function declares the builder's public keyword-only signature (every name of
    :data:`COMMON_PARAMETERS` plus the family's own parameters) and its docstring; its body is never run. A call binds
    the arguments to that signature (a missing or unknown argument is a ``TypeError``, as for any function), validates
    the common ones into :class:`CommonParams` (``randomize_actions`` forced off and a positive ``p_lazy`` rejected
    where the family says so), constructs ``family(**own parameters, **the common values its constructor names)``
    (the parameters of its ``reward_parameters`` bundled into one ``rewards`` argument) and returns :func:`build_mdp`
    of it.
    """
    wanted = [p for p in inspect.signature(family).parameters if p in COMMON_PARAMETERS]
    spec = family.reward_parameters

    def decorate(declaration: Callable[..., MDP]) -> Callable[..., MDP]:
        signature = inspect.signature(declaration)
        missing = [p for p in COMMON_PARAMETERS if p not in signature.parameters]
        if missing:
            raise TypeError(f"the builder {declaration.__name__} must declare the common parameters {missing}")
        wrong = [p for p, d in COMMON_DEFAULTS.items() if signature.parameters[p].default != d]
        if wrong:
            raise TypeError(f"the builder {declaration.__name__} must give {wrong} the defaults of COMMON_DEFAULTS")
        undeclared = [p for p in (spec.names if spec is not None else ()) if p not in signature.parameters]
        if undeclared:
            raise TypeError(f"the builder {declaration.__name__} must declare the reward parameters {undeclared}")

        @functools.wraps(declaration)
        def builder(*args: Any, **kwargs: Any) -> MDP:
            try:
                bound = signature.bind(*args, **kwargs)
            except TypeError as e:
                raise TypeError(f"{declaration.__name__}(): {e}") from None
            bound.apply_defaults()
            own = dict(bound.arguments)
            given = {p: own.pop(p) for p in COMMON_PARAMETERS}
            if not family.lazy_allowed and check_noise_probability("p_lazy", given["p_lazy"]) > 0:
                raise ValueError(
                    f"p_lazy must be None for {family.name} (it has no lazy mechanic); got {given['p_lazy']}"
                )
            if not family.randomize_actions_allowed:
                given["randomize_actions"] = False
            common = CommonParams(**given)
            passed = {p: getattr(common, p) for p in wanted}
            if spec is not None:
                values = {p: own.pop(p) for p in spec.names}
                passed["rewards"] = spec.arguments(
                    values, common.make_reward_stochastic, common.reward_variance_multiplier
                )
            fam = family(**own, **passed)
            return build_mdp(fam, common)

        return builder

    return decorate
