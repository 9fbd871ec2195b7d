"""jaxmdp: tabular MDPs as JAX pytrees, with exact dynamic programming and a functional environment API.

Rebuilds the MDP side of "Hardness in Markov Decision Processes: Theory and Practice" (Conserva & Rauber, NeurIPS
2022) so that many MDPs and many seeds run in lockstep under ``jit`` and ``vmap``.
"""

from jaxmdp.jaxlib_workarounds import xla_cpu as _xla_cpu

# Before anything can create a JAX backend: see jaxmdp/jaxlib_workarounds/xla_cpu.py (jaxlib 0.10.2 miscompiles some CPU
# reductions).
_xla_cpu.disable_ynn_fusion()

from jaxmdp import dynamic_programming  # noqa: E402
from jaxmdp._memory import NotEnoughMemory
from jaxmdp.blockmdp import (
    EMISSION_KINDS,
    NOISE_KINDS,
    BlockMDP,
    block_mdp,
    emission_table,
    observe,
    pad_observations,
)
from jaxmdp.batching import pad, permute_states, size_buckets, stack, state_permutation, unstack
from jaxmdp.communication import CommunicationClass, communication_class
from jaxmdp.env import EnvState, reset, sample_action, step
from jaxmdp.gymnax_env import as_gymnax
from jaxmdp.mdp import MDP, MDPInfo, custom_mdp
from jaxmdp.mdp_families import Beta, PointMass
from jaxmdp.registry import families, make, register
from jaxmdp.render import render
from jaxmdp.transforms import apply_noise, apply_p_lazy, apply_p_rand
from jaxmdp.values import ReferenceValues, optimal_value, random_value, reference_values, worst_value

__all__ = [
    "MDP",
    "MDPInfo",
    "custom_mdp",
    "make",
    "families",
    "register",
    "apply_p_rand",
    "apply_p_lazy",
    "apply_noise",
    "stack",
    "unstack",
    "size_buckets",
    "pad",
    "permute_states",
    "state_permutation",
    "EnvState",
    "reset",
    "step",
    "sample_action",
    "as_gymnax",
    "render",
    "dynamic_programming",
    "CommunicationClass",
    "communication_class",
    "ReferenceValues",
    "reference_values",
    "optimal_value",
    "worst_value",
    "random_value",
    "Beta",
    "PointMass",
    "BlockMDP",
    "block_mdp",
    "pad_observations",
    "emission_table",
    "observe",
    "EMISSION_KINDS",
    "NOISE_KINDS",
    "NotEnoughMemory",
]


def __getattr__(name: str):
    # jaxmdp.plotting imports matplotlib: loaded on first access only, so that `import jaxmdp` does not pay for it.
    if name == "plotting":
        import importlib

        return importlib.import_module("jaxmdp.plotting")
    raise AttributeError(f"module 'jaxmdp' has no attribute {name!r}")
