"""BlockMDPs (paper §3.1 and App. A.2): emission maps, emission noise and the BlockMDP environment.

* :func:`emission_table` -- the observation of every state under one of the six emission maps;
* :mod:`~jaxmdp.blockmdp.noise` -- the four emission noises;
* :class:`BlockMDP`, :func:`block_mdp`, :func:`observe` -- an MDP with its table and noise, usable with
  :func:`jaxmdp.reset`, :func:`jaxmdp.step` and :func:`jaxmdp.stack` like an MDP;
* :func:`pad_observations` -- zero-padded observations (marked by a mask), so that BlockMDPs of different emission
  shapes stack into one batch.
"""

from jaxmdp.blockmdp.block_mdp import BlockMDP, block_mdp, noise_key, observe, pad_observations
from jaxmdp.blockmdp.emission_maps import EMISSION_KINDS, emission_table, family_symbols, register_symbols
from jaxmdp.blockmdp.noise import NOISE_DEFAULTS, NOISE_KINDS

__all__ = [
    "BlockMDP",
    "block_mdp",
    "observe",
    "pad_observations",
    "noise_key",
    "emission_table",
    "EMISSION_KINDS",
    "NOISE_KINDS",
    "NOISE_DEFAULTS",
    "register_symbols",
    "family_symbols",
]
