"""Other runs' results set beside a run's own in its report: how a new agent meets the shipped ones without running
them again (docs/guide/own_agent.md).

Two sources (:func:`load`):

* ``"committed"``: the committed results of the shipped agents (:data:`COMMITTED_RUNS`, the run folders of
  ``docs/tables/`` that docs/results.md reports, plus the quick benchmark), shipped as package data in
  :data:`COMMITTED_FILE` (one row per member: run, set, MDP, agent, seed and the report's scores), so that an
  installed package has them without the repository;
* a run folder (its ``plan.json`` and ``members.csv``), e.g. the shipped agents run once at a protocol that has no
  committed results.

A source's results of an agent in a set are set beside a run (:func:`select`) only when they were made under the
run's protocol: the same steps, indicator log period, emission, agent rules, indicators and convergence stop, the
run's seeds and MDPs among theirs (the rows of exactly the run's seeds and MDPs are shown), and the hyperparameters
that the run's ``--hparams`` source gives that agent. The size buckets and member counts of a batch are not part of
the protocol: they change a member's random stream (its padding), not the distribution of its results. Results of
an agent that the run itself ran are not taken; a source with nothing comparable raises ``ValueError`` naming what
differs.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import os
from collections import defaultdict
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import agents as agent_registry
from hardness.benchmark import hparams as hp_sources
from hardness.benchmark import sets

__all__ = ["COMMITTED_FILE", "COMMITTED_RUNS", "SCORE_FIELDS", "CommittedRun", "Source", "Beside", "load",
           "committed", "from_run", "select", "write_committed"]

#: The package data: one row per member of the committed runs (:data:`COMMITTED_RUNS`).
COMMITTED_FILE = Path(__file__).with_name("data") / "committed_members.csv"
#: The columns of ``members.csv`` that a report reads, kept for every member of a source.
SCORE_FIELDS = ("normalized_regret_per_step", "normalized_cumulative_reward", "normalized_cumulative_expected_reward")


@dataclasses.dataclass(frozen=True)
class CommittedRun:
    """One committed run folder ``docs/tables/<folder>`` and the protocol it ran (its command is in
    docs/results.md): ``agents`` on ``sets``, every other setting the benchmark's default."""

    id: str
    folder: str
    sets: tuple[str, ...]
    agents: tuple[str, ...]
    n_steps: int
    seeds: tuple[int, ...]
    log_periods: Mapping[str, int] | None = None
    emission: str | None = None
    hparams_source: str = "tuned"

    def period(self, set_name: str) -> int:
        return int((self.log_periods or {}).get(set_name, 100))


_EP, _CONT = sets.SETTINGS[:2], sets.SETTINGS[2:]

#: The committed runs of the shipped agents, one per (agent, set) and protocol: each agent's results from the run
#: with the most seeds (seeds 0-1 of a 20-seed run serve a 2-seed run); a run's rows of other sets or agents are not
#: taken (a folder still being filled, as the 20-seed tabular run, holds parts of the runs that follow).
COMMITTED_RUNS: tuple[CommittedRun, ...] = (
    CommittedRun("continuous_20", "benchmark_continuous_full_20seeds", _CONT,
                 ("ucrl2", "q_learning_continuous", "random_continuous"), 500_000, tuple(range(20))),
    CommittedRun("episodic_20", "benchmark_episodic_full_20seeds_ql_random", _EP,
                 ("q_learning_episodic", "random_episodic"), 500_000, tuple(range(20))),
    CommittedRun("psrl_20", "benchmark_tabular_20seeds", sets.SETTINGS, ("psrl_continuous", "psrl_episodic"),
                 500_000, tuple(range(20))),
    *(CommittedRun(f"deep_{s.replace(' ', '_')}_20k", f"benchmark_deep_{s.replace(' ', '_')}_20k", (s,),
                   tuple(f"{a}_{s.split()[0]}" for a in ("dqn", "actor_critic", "actor_critic_rnn", "random")),
                   20_000, (0, 1, 2), emission="state_info")
      for s in sets.SETTINGS),
    CommittedRun("quick", "benchmark_quick", sets.QUICK_SETS,
                 ("q_learning_episodic", "psrl_episodic", "random_episodic", "q_learning_continuous", "ucrl2",
                  "random_continuous"), 1_000, (0, 1), {"episodic quick test": 1000, "continuous quick test": 500}),
)

#: SHA-256 of the shipped tuned file's values (:func:`_tuned_digest`) when the committed runs were made: a retuned
#: file makes their tabular results stale, and :func:`committed` then marks them so (rerun them, or recommit).
TUNED_DIGEST = "d677cc8342744cbde51bb12ffe05a9df6974b2332da348a36ee197eab022e84e"


@dataclasses.dataclass(frozen=True)
class Source:
    """One agent's results in one set from a source, and the protocol they were made under.

    ``protocol``: ``n_steps``, ``log_period``, ``emission``, ``agent_variant``, ``indicator_variant``,
    ``stop_when_converged``; ``hparams``: the agent's hyperparameters as a run's plan records them, or ``None``: those
    that the ``--hparams`` source ``hparams_from`` gives it today (resolved only when compared, so that reading the
    committed results imports no deep agent); ``stale``: why they no longer are what they claim (empty: they are);
    ``rows``: ``{(mdp, seed): {field: value}}`` of :data:`SCORE_FIELDS`."""

    origin: str
    set_name: str
    agent: str
    protocol: Mapping[str, Any]
    seeds: tuple[int, ...]
    hparams: Mapping[str, str] | None
    rows: Mapping[tuple[str, int], Mapping[str, float]]
    hparams_from: str = "tuned"
    stale: str = ""

    def their_hparams(self) -> Mapping[str, str]:
        if self.hparams is not None:
            return self.hparams
        return _hparams_repr(hp_sources.hparams_for(self.agent, self.hparams_from))


@dataclasses.dataclass
class Beside:
    """What :func:`select` sets beside a run: ``agents`` ``{set: [agent]}``, their ``scores``
    ``{(set, mdp, agent): {field: [value per seed]}}``, the ``origin`` of each ``{(set, agent): origin}``, and the
    source's agents ``left_out`` ``{(set, agent): [what differs]}``."""

    label: str
    description: str
    agents: dict[str, list[str]]
    scores: dict[tuple[str, str, str], dict[str, list[float]]]
    origin: dict[tuple[str, str], str]
    left_out: dict[tuple[str, str], list[str]]


def _tuned_digest(path: str | os.PathLike = hp_sources.TUNED_FILE) -> str:
    values = {a: e.get("values") for a, e in sorted(hp_sources.load_tuned(path).items())}
    return hashlib.sha256(json.dumps(values, sort_keys=True).encode()).hexdigest()


def _protocol(n_steps: int, log_period: int, emission: str | None, agent_variant: str = "paper",
              indicator_variant: str = "paper", stop_when_converged: bool = False) -> dict[str, Any]:
    return dict(n_steps=int(n_steps), log_period=int(log_period), emission=emission, agent_variant=agent_variant,
                indicator_variant=indicator_variant, stop_when_converged=bool(stop_when_converged))


def _hparams_repr(hp: Any) -> dict[str, str]:
    return {f.name: repr(np.asarray(getattr(hp, f.name)).tolist()) for f in dataclasses.fields(hp)}


def write_committed(tables: str | os.PathLike, path: str | os.PathLike = COMMITTED_FILE) -> int:
    """Write the package data :data:`COMMITTED_FILE` from the committed run folders under ``tables``
    (``docs/tables``): the rows of every :data:`COMMITTED_RUNS` entry's agents and sets, values copied as written.
    Returns the number of rows. Run it when a committed run folder changes."""
    out = []
    for run in COMMITTED_RUNS:
        with (Path(tables) / run.folder / "members.csv").open(newline="") as f:
            for r in csv.DictReader(f):
                if r["agent"] in run.agents and r["set"] in run.sets and int(r["seed"]) in run.seeds:
                    out.append([run.id, r["set"], r["mdp"], r["agent"], r["seed"], *(r[k] for k in SCORE_FIELDS)])
    tmp = Path(path).with_name(Path(path).name + ".tmp")
    with tmp.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["run", "set", "mdp", "agent", "seed", *SCORE_FIELDS])
        w.writerows(out)
    os.replace(tmp, path)
    return len(out)


def committed(path: str | os.PathLike = COMMITTED_FILE) -> list[Source]:
    """The committed results (:data:`COMMITTED_RUNS`) as sources, read from the package data ``path``."""
    rows: dict[tuple[str, str, str], dict[tuple[str, int], dict[str, float]]] = defaultdict(dict)
    with Path(path).open(newline="") as f:
        for r in csv.DictReader(f):
            rows[(r["run"], r["set"], r["agent"])][(r["mdp"], int(r["seed"]))] = {k: float(r[k]) for k in SCORE_FIELDS}
    stale = ""
    if _tuned_digest() != TUNED_DIGEST:
        stale = ("the shipped tuned file changed since the committed results were made: they no longer are the "
                 "tuned agents' (rerun them and update hardness/benchmark/baselines.py)")
    out = []
    for run in COMMITTED_RUNS:
        for set_name in run.sets:
            for agent in run.agents:
                if not rows[(run.id, set_name, agent)]:
                    continue  # an agent of the other setting type
                tabular_tuned = agent in hp_sources.SEARCH_SPACES and run.hparams_source == "tuned"
                out.append(Source(
                    origin=f"docs/tables/{run.folder}", set_name=set_name, agent=agent,
                    protocol=_protocol(run.n_steps, run.period(set_name), run.emission), seeds=run.seeds,
                    hparams=None, hparams_from=run.hparams_source, rows=rows[(run.id, set_name, agent)],
                    stale=stale if tabular_tuned else ""))
    return out


def from_run(folder: str | os.PathLike) -> list[Source]:
    """The results of a run folder (``plan.json``, ``members.csv``) as sources, one per (set, agent) of its plan."""
    folder = Path(folder)
    if not (folder / "plan.json").exists() or not (folder / "members.csv").exists():
        raise ValueError(f"baseline {folder} holds no benchmark run (plan.json and members.csv)")
    settings = json.loads((folder / "plan.json").read_text())["settings"]
    rows: dict[tuple[str, str], dict[tuple[str, int], dict[str, float]]] = defaultdict(dict)
    with (folder / "members.csv").open(newline="") as f:
        for r in csv.DictReader(f):
            rows[(r["set"], r["agent"])][(r["mdp"], int(r["seed"]))] = {k: float(r[k]) for k in SCORE_FIELDS}
    return [
        Source(origin=str(folder), set_name=s, agent=a, protocol=run_protocol(settings, s),
               seeds=tuple(int(x) for x in settings["seeds"]), hparams=settings["hparams"][a], rows=rows[(s, a)])
        for s in settings["sets"] for a in settings["agents"][s]
    ]


def load(baseline: str | os.PathLike) -> tuple[str, str, list[Source]]:
    """``(label, description, sources)`` of ``baseline``: ``"committed"`` or a run folder (module docstring)."""
    if str(baseline) == "committed":
        return "committed", ("the committed results of the shipped agents (package data, from the run folders "
                             "`docs/tables/<folder>` of docs/results.md)"), committed()
    folder = Path(baseline)
    return folder.name, f"the run in `{folder}`", from_run(folder)


def run_protocol(settings: Mapping[str, Any], set_name: str) -> dict[str, Any]:
    """The protocol (:class:`Source`) of a run's ``plan.json`` ``settings`` in ``set_name``."""
    return _protocol(settings["n_steps"], settings["log_periods"][set_name], settings.get("emission"),
                     settings.get("agent_variant", "paper"), settings.get("variant", "paper"),
                     settings.get("stop_when_converged", False))


def _seeds_text(seeds: Sequence[int]) -> str:
    seeds = sorted(int(s) for s in seeds)
    if seeds and seeds == list(range(seeds[0], seeds[-1] + 1)) and len(seeds) > 2:
        return f"{seeds[0]}-{seeds[-1]}"
    return ", ".join(map(str, seeds))


def _differences(source: Source, settings: Mapping[str, Any], set_name: str, labels: Sequence[str]) -> list[str]:
    """What differs between the run's protocol in ``set_name`` and ``source``'s (empty: comparable)."""
    ours = run_protocol(settings, set_name)
    diffs = [f"{k} {ours[k]!r} here, {source.protocol[k]!r} there" for k in ours if ours[k] != source.protocol[k]]
    missing = sorted(set(int(s) for s in settings["seeds"]) - set(source.seeds))
    if missing:
        diffs.append(f"seeds {_seeds_text(settings['seeds'])} here, {_seeds_text(source.seeds)} there")
    unfinished = [(m, int(s)) for m in labels for s in settings["seeds"] if (m, int(s)) not in source.rows]
    if not missing and unfinished:
        diffs.append(f"{len(unfinished)} of this run's (MDP, seed) members missing there (e.g. {unfinished[0]})")
    if source.stale:
        diffs.append(source.stale)
    elif not diffs and source.agent in agent_registry.AGENTS:  # an agent of a run folder that is not registered
        # here keeps the hyperparameters its folder records: the run's --hparams does not apply to it
        try:
            hp = _hparams_repr(hp_sources.hparams_for(source.agent, settings["hparams_source"],
                                                      settings.get("agent_variant", "paper")))
        except ValueError as err:
            return [f"hyperparameters: {err}"]
        theirs = source.their_hparams()
        fields = sorted(k for k in set(hp) | set(theirs) if hp.get(k) != theirs.get(k))
        if fields:
            diffs.append(f"hyperparameters: --hparams {settings['hparams_source']} gives {source.agent} "
                         f"{', '.join(f'{k}={hp.get(k)}' for k in fields)} here, "
                         f"{', '.join(f'{k}={theirs.get(k)}' for k in fields)} there")
    return diffs


def select(settings: Mapping[str, Any], labels: Mapping[str, Sequence[str]], baseline: str | os.PathLike) -> Beside:
    """What of ``baseline`` (:func:`load`) to set beside a run of plan ``settings`` holding the MDPs ``labels``
    ``{set: [label]}`` (module docstring); ``ValueError`` naming what differs when nothing is comparable."""
    label, description, sources = load(baseline)
    found = Beside(label, description, {s: [] for s in settings["sets"]}, {}, {}, {})
    seeds = [int(s) for s in settings["seeds"]]
    for set_name in settings["sets"]:
        own = set(settings["agents"][set_name])
        candidates: dict[str, list[Source]] = defaultdict(list)
        for src in sources:
            if src.set_name == set_name and src.agent not in own:
                candidates[src.agent].append(src)
        for agent, srcs in candidates.items():
            diffs = [_differences(src, settings, set_name, labels[set_name]) for src in srcs]
            ok = [src for src, d in zip(srcs, diffs) if not d]
            if not ok:
                found.left_out[(set_name, agent)] = diffs[0]
                continue
            src = ok[0]
            found.agents[set_name].append(agent)
            found.origin[(set_name, agent)] = src.origin
            for mdp in labels[set_name]:
                cell = found.scores.setdefault((set_name, mdp, agent), {k: [] for k in SCORE_FIELDS})
                for seed in seeds:
                    for k in SCORE_FIELDS:
                        cell[k].append(src.rows[(mdp, seed)][k])
    if not any(found.agents.values()):
        detail = "; ".join(f"{a} in {s}: {', '.join(d)}" for (s, a), d in found.left_out.items())
        sets_there = sorted({src.set_name for src in sources})
        raise ValueError(f"cannot set {description} beside this run: "
                         + (f"its protocol differs ({detail})" if detail else
                            f"they hold no other agent of its sets {list(settings['sets'])} (they have {sets_there})"))
    return found
