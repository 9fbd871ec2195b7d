"""The plan of a benchmark folder (``plan.json``): every batch that any call on the folder planned, merged.

A folder holds one protocol: the settings in :data:`PROTOCOL` (seeds, steps, hyperparameter source, agent rules,
buckets, records, emission, indicators, MDP filter, convergence stop) are the same for every call on it, and a call
of other settings is refused (``ValueError`` naming each difference), since its batches would compute other numbers
for the same (set, MDP, agent, seed). Within a protocol the sets, the agents of each set, the log period of each set,
each agent's hyperparameters and size buckets add up: a call that names fewer agents or sets than the folder holds
keeps the others, so ``members.csv``, ``batches.csv`` and the report cover every finished batch in the folder
whichever subset the last call named. A set's log period, an agent's hyperparameters and its size buckets must agree
between the calls that name them.

Order: a list (sets, or a set's agents) of the call that holds every entry of the folder's is taken as it is, a
folder's list that holds every entry of the call's is kept, and otherwise the call's new entries follow the folder's;
so a folder run in one call, in shards of one command, or first with fewer agents and then with all of them ends with
the plan (and ``members.csv``) of the single call that names everything.

Batches are merged per *root*, the batch as first planned (a batch split because it did not fit in memory,
:func:`hardness.benchmark.run.split_batch`, is replaced by its parts; the parts share the root): the folder's version
of a root is kept, unless ``finished`` says that only another version has finished (when folders are merged).

Plans are dictionaries as ``plan.json`` stores them: ``{"settings": {...}, "batches": [{"id", "key", "set_name",
"agent", "members", "whole"}, ...]}``. Every read-merge-write happens under the folder's lock
(:func:`hardness.benchmark.claims.folder_lock`), so that processes sharing a folder never lose each other's batches.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from hardness.benchmark.claims import folder_lock
from hardness.benchmark.tables import _write_atomic, write_tables

__all__ = ["PROTOCOL", "load", "save", "merge_settings", "merge", "commit", "commit_call", "replace", "root", "pairs",
           "to_batch", "call_batches", "CallView", "write_folder_tables"]

#: Settings that every call on one folder shares (``plan.json`` ``settings`` keys).
PROTOCOL = ("seeds", "n_steps", "hparams_source", "agent_variant", "n_buckets", "max_members", "n_records",
            "emission", "observations", "variant", "only", "stop_when_converged")

Plan = dict[str, Any]


@dataclasses.dataclass(frozen=True)
class Batch:
    """One runner call: ``agent`` on ``members`` (``(MDP label, seed)``) of ``set_name``; ``key`` hashes everything
    its results depend on."""

    id: str
    key: str
    set_name: str
    agent: str
    members: tuple[tuple[str, int], ...]
    #: The members of the batch this one is a part of, when a batch was split because it did not fit in memory
    #: (:func:`hardness.benchmark.run.split_batch`): the part is padded and sized like it, so each member runs as it
    #: would have there.
    whole: tuple[tuple[str, int], ...] | None = None


def to_batch(b: Mapping[str, Any]) -> Batch:
    """A batch of ``plan.json`` as a :class:`Batch`."""
    return Batch(b["id"], b["key"], b["set_name"], b["agent"], tuple(map(tuple, b["members"])),
                 None if b.get("whole") is None else tuple(map(tuple, b["whole"])))


def load(out: str | os.PathLike) -> Plan | None:
    """The plan in folder ``out`` (``None`` when it has none)."""
    path = Path(out) / "plan.json"
    return json.loads(path.read_text()) if path.exists() else None


def save(out: str | os.PathLike, plan: Plan) -> None:
    """Write ``plan`` to ``out/plan.json`` atomically."""
    Path(out).mkdir(parents=True, exist_ok=True)
    _write_atomic(Path(out) / "plan.json", json.dumps(plan, indent=1) + "\n")


def root(batch: dict) -> tuple:
    """The root of a batch: ``(set, agent, members of the batch as first planned)``."""
    members = batch.get("whole") or batch["members"]
    return batch["set_name"], batch["agent"], tuple(tuple(m) for m in members)


def pairs(plan: Plan) -> list[tuple[str, str]]:
    """The ``(set, agent)`` pairs of a plan, in its order."""
    s = plan["settings"]
    return [(set_name, agent) for set_name in s["sets"] for agent in s["agents"][set_name]]


def _order(there: Sequence, here: Sequence) -> list:
    """The merged order of a list (module docstring)."""
    if set(here) >= set(there):
        return list(here)
    return list(there) + [x for x in here if x not in there]


def _buckets(settings: dict, agent: str) -> int:
    return int(settings.get("agent_buckets", {}).get(agent, settings["n_buckets"]))


def _differences(there: dict, here: dict) -> list[str]:
    diffs = [f"{k}: {there.get(k)!r} there, {here.get(k)!r} here" for k in PROTOCOL if there.get(k) != here.get(k)]
    if diffs:  # bucket counts and log periods follow from the protocol's differences
        return diffs
    for s in set(there["sets"]) & set(here["sets"]):
        if there["log_periods"][s] != here["log_periods"][s]:
            diffs.append(f"log period of {s!r}: {there['log_periods'][s]} there, {here['log_periods'][s]} here")
    agents_there = {a for s in there["sets"] for a in there["agents"][s]}
    for a in sorted(agents_there & {a for s in here["sets"] for a in here["agents"][s]}):
        if there["hparams"][a] != here["hparams"][a]:
            diffs.append(f"hyperparameters of {a}: {there['hparams'][a]} there, {here['hparams'][a]} here")
        if _buckets(there, a) != _buckets(here, a):
            diffs.append(f"size buckets of {a}: {_buckets(there, a)} there, {_buckets(here, a)} here")
    return diffs


def merge_settings(there: dict, here: dict, where: str = "the folder") -> dict:
    """The settings of a folder whose plan has settings ``there`` after a call with settings ``here`` (module
    docstring); ``ValueError`` naming every difference of protocol."""
    diffs = _differences(there, here)
    if diffs:
        raise ValueError(f"{where} holds a benchmark run of another protocol ({'; '.join(diffs)}); a folder holds "
                         "one protocol: run these settings in another folder (more agents or sets of the same "
                         "protocol add to a folder)")
    names = _order(there["sets"], here["sets"])
    agents = {s: _order(there["agents"].get(s, []), here["agents"].get(s, [])) for s in names}
    every = list(dict.fromkeys(a for s in names for a in agents[s]))
    hparams = {a: here["hparams"][a] if a in here["hparams"] else there["hparams"][a] for a in every}
    merged = {**there, **here}
    merged.update(sets=names, agents=agents, hparams=hparams,
                  log_periods={s: {**there["log_periods"], **here["log_periods"]}[s] for s in names},
                  agent_buckets={a: b for a in every
                                 if (b := _buckets(here if a in here["hparams"] else there, a)) != here["n_buckets"]})
    return {k: merged[k] for k in here}  # the key order of a call's settings


def merge(
    there: Plan | None,
    here: Plan,
    *,
    where: str = "the folder",
    finished: Callable[[dict, int], bool] | None = None,
) -> Plan:
    """Plan ``here`` merged into the folder's plan ``there`` (module docstring). ``finished(batch, k)``: whether
    ``batch`` of the ``k``-th plan (0: ``there``, 1: ``here``) has finished; a root's version that has finished in
    full is taken before the folder's."""
    if there is None:
        return {"settings": here["settings"], "batches": list(here["batches"])}
    settings = merge_settings(there["settings"], here["settings"], where)
    versions: dict[tuple, list[tuple[int, list[dict]]]] = {}  # root -> [(plan, its batches of the root)]
    order: dict[tuple[str, str], list[tuple]] = {}  # pair -> its roots, in the first plan's order
    for k, p in enumerate((there, here)):
        for b in p["batches"]:
            r = root(b)
            have = versions.setdefault(r, [])
            if not have or have[-1][0] != k:
                have.append((k, []))
                if r not in order.setdefault(r[:2], []):
                    order[r[:2]].append(r)
            have[-1][1].append(b)
    batches = []
    for pair in pairs({"settings": settings}):
        for r in order.get(pair, []):
            chosen = versions[r][0][1]
            if finished is not None:
                done = [v for k, v in versions[r] if all(finished(b, k) for b in v)]
                chosen = done[0] if done else chosen
            batches += chosen
    return {"settings": settings, "batches": batches}


def commit(out: str | os.PathLike, here: Plan) -> Plan:
    """Merge ``here`` into ``out``'s plan under the folder's lock and write it; returns the folder's plan."""
    with folder_lock(out):
        merged = merge(load(out), here, where=str(out))
        save(out, merged)
    return merged


def commit_call(out: str | os.PathLike, settings: dict, batches: Sequence[Batch]) -> list[Batch]:
    """Merge a call's plan (``settings``, ``batches``) into ``out``'s (:func:`commit`); returns the call's batches
    there (:func:`call_batches`)."""
    folder = commit(out, {"settings": settings, "batches": [dataclasses.asdict(b) for b in batches]})
    return call_batches(folder, settings)


def replace(out: str | os.PathLike, batch: dict, parts: Sequence[dict]) -> Plan:
    """Replace ``batch`` by ``parts`` in ``out``'s plan under the folder's lock (nothing changes when another process
    did it first); returns the folder's plan."""
    with folder_lock(out):
        plan = load(out)
        ids = [b["id"] for b in plan["batches"]]
        if batch["id"] in ids:
            at = ids.index(batch["id"])
            plan["batches"][at : at + 1] = list(parts)
            save(out, plan)
    return plan


def call_batches(folder: Plan, settings: dict) -> list[Batch]:
    """The batches of a call of plan ``settings`` in the folder's plan (splits included), in the call's order of
    (set, agent) pairs, so that shares (:func:`hardness.benchmark.shards.share`) do not depend on other calls."""
    order = {pair: k for k, pair in enumerate(pairs({"settings": settings}))}
    mine = [b for b in folder["batches"] if (b["set_name"], b["agent"]) in order]
    return [to_batch(b) for b in sorted(mine, key=lambda b: order[b["set_name"], b["agent"]])]


class CallView:
    """A call's batches in the folder's plan, read again whenever ``plan.json`` changes (another process split a
    batch)."""

    def __init__(self, out: Path, settings: dict, batches: list[Batch]):
        self.out, self.settings, self.batches = Path(out), settings, batches
        self._stat = self._stamp()

    def _stamp(self) -> tuple:
        st = (self.out / "plan.json").stat()
        return st.st_ino, st.st_mtime_ns, st.st_size

    def share(self, shard: tuple[int, int] | None) -> list[Batch]:
        """The call's batches, or those of shard ``(i, N)`` (:func:`hardness.benchmark.shards.share`)."""
        from hardness.benchmark import shards

        stamp = self._stamp()
        if stamp != self._stat:
            self.batches, self._stat = call_batches(load(self.out), self.settings), stamp
        return self.batches if shard is None else shards.share(self.batches, shard)


def write_folder_tables(out: str | os.PathLike) -> int:
    """Write ``members.csv`` and ``batches.csv`` of every finished batch in the folder's plan, under its lock
    (:func:`hardness.benchmark.tables.write_tables`); returns the number of member rows."""
    with folder_lock(out):
        folder = load(out)
        return write_tables(Path(out), folder["settings"], [to_batch(b) for b in folder["batches"]])
