"""Checkpoints of a lockstep run: the loop's carry and the records so far, tied to the run that made them.

A checkpoint is one ``.npz`` file (the carry's leaves, the records, and a JSON ``meta`` entry) written atomically
after each chunk; :func:`fingerprint` hashes everything that defines a run's results, so a checkpoint resumes only
the run that made it.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxmdp.experiment.members import Grid

__all__ = ["fingerprint", "save_checkpoint", "load_checkpoint"]


def fingerprint(agent_name: str, g: Grid, n_steps: int, log_period: int, record_period: int, variant: str) -> str:
    """A hash of everything that defines a run's results (MDPs, hyperparameters, keys and settings): a checkpoint
    resumes only the run that made it."""
    h = hashlib.sha256()
    for x in jax.tree.leaves(g.mdps) + jax.tree.leaves(g.hparams) + [g.mdp_index, g.key_data]:
        a = np.ascontiguousarray(np.asarray(x))
        h.update(str((a.shape, a.dtype)).encode())
        h.update(a.tobytes())
    h.update(repr((agent_name, n_steps, log_period, record_period, variant)).encode())
    return h.hexdigest()


def save_checkpoint(path: Path, carry: Any, steps: np.ndarray, values: np.ndarray, meta: dict) -> None:
    """Save the loop's carry, the records so far and ``meta`` to ``path`` (``.npz``), atomically (write + rename)."""
    leaves = jax.tree.leaves(carry)
    arrays = {f"leaf{i}": np.asarray(x) for i, x in enumerate(leaves)}
    arrays["record_steps"] = steps
    arrays["record_values"] = values
    arrays["meta"] = np.asarray(json.dumps(meta))
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez(tmp, **arrays)
    os.replace(tmp, path)


def load_checkpoint(path: Path, like: Any, expected: str) -> tuple[Any, np.ndarray, np.ndarray, dict]:
    """``(carry, record steps, record values, meta)`` from ``path``; ``ValueError`` unless the checkpoint's
    fingerprint is ``expected`` and its arrays match the structure of ``like``."""
    with np.load(path) as z:
        meta = json.loads(str(z["meta"]))
        if meta.get("fingerprint") != expected:
            raise ValueError(
                f"checkpoint {path} belongs to a different run (agent, grid, n_steps, periods or variant differ)"
            )
        leaves, treedef = jax.tree.flatten(like)
        new = []
        for i, ref in enumerate(leaves):
            a = z[f"leaf{i}"]
            if a.shape != ref.shape or a.dtype != ref.dtype:
                raise ValueError(f"checkpoint {path} does not match this run's state (leaf {i}: {a.shape} {a.dtype})")
            new.append(jnp.asarray(a))
        return jax.tree.unflatten(treedef, new), z["record_steps"], z["record_values"], meta
