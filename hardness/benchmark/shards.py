"""A benchmark split over machines: shares of the batches (``run --shard i/N``) and merged folders (``report DIR1 DIR2
... --out DIR``).

Share: the batches of a call in the plan's order (sets, a set's agents, an agent's size buckets; parts of a batch
split to fit in memory count as the batch they came from) are dealt to the ``N`` shards in a snake, ``0, 1, ..., N-1,
N-1, ..., 1, 0, 0, 1, ...``, so that each shard gets a share of every agent's small and large buckets rather than
one shard all the largest. The share depends only on the plan, so every job of an array started with the same command
and its own ``i`` runs its own batches, whether the jobs write one shared folder or a folder each.

Merge: the folders' plans are merged (:func:`hardness.benchmark.plans.merge`: one protocol, refused otherwise) and
each finished batch's files (``runs/<batch>.json``, ``.curves.npz``, the runner's ``.csv`` and the claims' ``.log``)
are copied from the first folder that finished it; ``members.csv`` and ``batches.csv`` are then written from them as
in a single run, so the merged folder's tables and report are the single run's (``batches.csv``'s timings, hosts and
pids, and the report's steps per second, are those of the machines that ran each batch).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from hardness.benchmark import plans

if TYPE_CHECKING:
    from hardness.benchmark.plans import Batch

__all__ = ["parse_shard", "check_shard", "shard_of", "share", "merge_folders"]

#: The files of a finished batch in ``runs/``.
BATCH_FILES = (".json", ".curves.npz", ".csv", ".log")


def check_shard(shard: tuple[int, int]) -> tuple[int, int]:
    """``shard`` as ``(i, N)`` integers with ``0 <= i < N``; ``ValueError`` otherwise."""
    try:
        i, n = shard
        ok = all(isinstance(x, int) and not isinstance(x, bool) for x in (i, n)) and 0 <= i < n
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"shard must be (i, N) with integers 0 <= i < N (shard i of N, counted from 0); got {shard!r}")
    return i, n


def parse_shard(text: str) -> tuple[int, int]:
    """``"i/N"`` (``--shard``) as ``(i, N)``: shard ``i`` of ``N``, counted from 0; ``ValueError`` naming the form."""
    parts = str(text).strip().split("/")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts) or not int(parts[0]) < int(parts[1]):
        raise ValueError(f"--shard must be i/N with integers 0 <= i < N (shard i of N, counted from 0, e.g. 0/4 to "
                         f"3/4 for four jobs); got {text!r}")
    return int(parts[0]), int(parts[1])


def shard_of(position: int, n: int) -> int:
    """The shard of the ``position``-th batch of a plan among ``n`` shards (a snake: module docstring)."""
    k = position % (2 * n)
    return k if k < n else 2 * n - 1 - k


def share(batches: Sequence[Batch], shard: tuple[int, int]) -> list[Batch]:
    """The batches of ``batches`` (a call's plan, in order) that shard ``(i, N)`` runs (module docstring)."""
    i, n = check_shard(shard)
    position: dict[tuple, int] = {}
    out = []
    for b in batches:
        r = (b.set_name, b.agent, b.whole or b.members)
        position.setdefault(r, len(position))
        if shard_of(position[r], n) == i:
            out.append(b)
    return out


def _finished_in(folder: Path, batch: dict) -> bool:
    from hardness.benchmark.tables import _finished

    return _finished(folder / "runs", plans.to_batch(batch)) is not None


def _copy(src: Path, dst: Path) -> None:
    tmp = dst.with_name(dst.name + ".tmp")
    shutil.copyfile(src, tmp)
    os.replace(tmp, dst)


def merge_folders(sources: Sequence[str | os.PathLike], out: str | os.PathLike) -> plans.Plan:
    """Merge the run folders ``sources`` into ``out`` (module docstring; ``out`` may be one of them or hold a run
    of the same protocol already) and write its ``plan.json``, ``members.csv`` and ``batches.csv``; returns the
    merged plan. ``ValueError`` for a folder without a run or of another protocol."""
    out = Path(out)
    folders = [Path(s) for s in sources]
    if not folders:
        raise ValueError("name at least one run folder to merge")
    for f in folders:
        if plans.load(f) is None:
            raise ValueError(f"{f} holds no benchmark run (plan.json)")
    if out.resolve() not in {f.resolve() for f in folders} and plans.load(out) is not None:
        folders.insert(0, out)
    merged = None
    for f in folders:
        merged = plans.merge(merged, plans.load(f), where=str(f),
                             finished=lambda b, k: any(_finished_in(g, b) for g in folders))
    (out / "runs").mkdir(parents=True, exist_ok=True)
    for b in merged["batches"]:
        if _finished_in(out, b):
            continue
        src = next((f for f in folders if _finished_in(f, b)), None)
        if src is None:
            continue
        for suffix in BATCH_FILES:
            path = src / "runs" / f"{b['id']}{suffix}"
            if path.exists():
                _copy(path, out / "runs" / path.name)
    plans.save(out, merged)
    plans.write_folder_tables(out)
    return merged
