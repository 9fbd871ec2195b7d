"""The emission maps of a benchmark run with the deep agents (benchmark.md §5-6): the reference's class names, the
kinds of :func:`jaxmdp.block_mdp` they are, and the per-seed key of the random ones."""

from __future__ import annotations

import jax

import jaxmdp
from jaxmdp._checks import did_you_mean
from jaxmdp.blockmdp.emission_maps import emission_shape
from jaxmdp.mdp import MDP

__all__ = ["REFERENCE_EMISSIONS", "KEYED_EMISSIONS", "EMISSION_STREAM", "canonical_emission", "emission_key",
           "to_block_mdp", "observation_shape"]


#: The reference's emission-map class names (benchmark.md §5) and the kinds of :func:`jaxmdp.block_mdp` they are.
REFERENCE_EMISSIONS = {
    "StateInfo": "state_info", "OneHotEncoding": "one_hot", "ImageEncoding": "image", "TensorEncoding": "tensor",
    "StateLinearOptimal": "linear_optimal", "StateLinearRandom": "linear_random",
}
#: Emission kinds whose features are random: their key is derived from the member's seed (:func:`emission_key`).
KEYED_EMISSIONS = ("linear_optimal", "linear_random")
#: ``fold_in`` constant of the emission key's stream (ASCII "emis"), apart from the agent's ``jax.random.key(seed)``.
EMISSION_STREAM = 0x656D6973


def canonical_emission(emission: str) -> str:
    """The :data:`jaxmdp.EMISSION_KINDS` name of ``emission``: a kind name (``"state_info"``) or a reference class
    name (``"StateInfo"``, :data:`REFERENCE_EMISSIONS`); ``ValueError`` listing the closest names otherwise."""
    name = REFERENCE_EMISSIONS.get(emission, emission)
    if name in jaxmdp.EMISSION_KINDS:
        return name
    known = list(jaxmdp.EMISSION_KINDS) + list(REFERENCE_EMISSIONS)
    raise ValueError(f"unknown emission {emission!r}{did_you_mean(emission, known)} "
                     f"Known: {', '.join(map(repr, known))}")


def emission_key(seed: int) -> jax.Array:
    """The key of a keyed emission (:data:`KEYED_EMISSIONS`) for the member of seed ``seed``:
    ``fold_in(jax.random.key(seed), EMISSION_STREAM)``, so the same seed gives the same features on every run and
    the features' stream is not the agent's (whose key is ``jax.random.key(seed)``)."""
    return jax.random.fold_in(jax.random.key(int(seed)), EMISSION_STREAM)


def to_block_mdp(mdp: MDP, emission: str, seed: int) -> jaxmdp.BlockMDP:
    """``mdp`` seen through ``emission`` (a kind or reference class name; no noise, as the reference's benchmark,
    benchmark.md §6): :func:`jaxmdp.block_mdp`, with :func:`emission_key` of ``seed`` for the linear kinds. This is
    how the deep agents run on the benchmark's sets (the paper's non-tabular benchmark uses ``StateInfo``)."""
    kind = canonical_emission(emission)
    key = emission_key(seed) if kind in KEYED_EMISSIONS else None
    return jaxmdp.block_mdp(mdp, kind, key=key)


def observation_shape(mdp: MDP, emission: str, seed: int) -> tuple[int, ...]:
    """``to_block_mdp(mdp, emission, seed).obs_shape`` without building the emission table
    (:func:`jaxmdp.blockmdp.emission_maps.emission_shape`; the linear kinds' features are a value iteration per MDP);
    where the MDP cannot produce ``emission``, the table's own error."""
    shape = emission_shape(mdp, canonical_emission(emission))
    return to_block_mdp(mdp, emission, seed).obs_shape if shape is None else shape
