"""Random hyperparameter search of the benchmark (paper App. F; benchmark.md §7, agents.md §8).

For one agent: ``n_candidates`` candidates drawn as the reference draws them
(:func:`hardness.benchmark.hparams.reference_candidates`, seeds ``42, 43, ...``), optionally with the reference's
cached values as one more candidate; the MDPs are the search set of the agent's setting (``n_per_family`` parameter
sets from every family's sampler, seed 42, :mod:`hardness.benchmark.samplers`), each built once per seed (the same
integer seed builds the MDP and seeds the agent). Every (candidate, MDP, seed) runs ``n_steps`` steps; the objective of
a candidate is the arithmetic mean over its MDPs and seeds of the **final** ``normalized_cumulative_regret`` (not
divided by the steps), and the candidate with the lowest objective wins (the first on ties).

Batching: the MDP instances are split into size buckets (:func:`jaxmdp.size_buckets`); each bucket is one runner call
whose members are every candidate on every instance of the bucket, so one compiled program per bucket serves all
candidates and no small MDP pays for the largest one's padding.

Budget: the reference's code defaults are 50 candidates, 5 MDPs per family, 3 seeds, 250 000 steps (the paper says
50 candidates, 12 MDPs per family, 200 000 steps), each run cut off after 300 s of wall clock. Here every run
completes its steps, and ``max_states`` may leave out the largest sampled MDPs to fit a smaller machine (the
provenance records it).
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np

import agents as agent_registry
import jaxmdp
from hardness.benchmark import hparams as hp_sources
from agents.search_spaces import SEARCH_SPACES, search_space
from hardness.benchmark import sets
from jaxmdp import runner
from jaxmdp.agent_interface import Agent
from jaxmdp.experiment.progress import LOG_EVERY_S, Progress
from jaxmdp.mdp import MDP

__all__ = ["Budget", "SearchResult", "check_tunable", "evaluate", "select", "search", "tuned_entry", "provenance",
           "write_tuned", "start_tuned_file"]

#: The reference's code-default budget for tabular agents (benchmark.md §7).
REFERENCE_BUDGET = dict(n_steps=250_000, n_candidates=50, n_per_family=5, n_seeds=3)


@dataclasses.dataclass(frozen=True)
class Budget:
    """A search budget: steps per run, sampled candidates, MDP samples per family, seeds ``0 .. n_seeds - 1``,
    indicator log period, the seed of the candidate and MDP draws, and the largest MDP kept (``None``: all)."""

    n_steps: int = REFERENCE_BUDGET["n_steps"]
    n_candidates: int = REFERENCE_BUDGET["n_candidates"]
    n_per_family: int = REFERENCE_BUDGET["n_per_family"]
    n_seeds: int = REFERENCE_BUDGET["n_seeds"]
    log_period: int = 100
    search_seed: int = 42
    max_states: int | None = None
    include_reference: bool = True

    @property
    def reduced(self) -> bool:
        """Whether this is less than the reference's code-default budget."""
        return any(getattr(self, k) < v for k, v in REFERENCE_BUDGET.items()) or self.max_states is not None


@dataclasses.dataclass
class SearchResult:
    """The scores of every candidate.

    Attributes:
      agent: the agent's name.
      labels: ``[C]`` candidate labels (``"sample_i"``, ``"reference"``).
      values: ``[C]`` the candidates' search-space values.
      scores: ``[C, N]`` final ``normalized_cumulative_regret`` of every candidate on each of the ``N`` (MDP, seed).
      members: ``[N]`` ``(MDP label, seed)`` of the columns of ``scores``.
      left_out: labels of the sampled MDPs left out by ``max_states``.
      run_s, compile_s: seconds spent running and compiling.
    """

    agent: str
    labels: list[str]
    values: list[dict[str, float]]
    scores: np.ndarray
    members: list[tuple[str, int]]
    left_out: list[str]
    run_s: float
    compile_s: float

    @property
    def objective(self) -> np.ndarray:
        """``[C]`` mean final normalised cumulative regret over MDPs and seeds."""
        return self.scores.mean(axis=1)

    @property
    def best(self) -> int:
        return select(self.scores)


def select(scores: np.ndarray) -> int:
    """The winning candidate: the lowest mean score over its (MDP, seed) columns (the first on ties)."""
    scores = np.asarray(scores, np.float64)
    if scores.ndim != 2 or scores.size == 0 or not np.all(np.isfinite(scores)):
        raise ValueError(f"scores must be a finite [candidates, runs] array; got shape {scores.shape}")
    return int(np.argmin(scores.mean(axis=1)))


def evaluate(
    agent: Agent,
    candidates: Sequence[Any],
    mdps: Sequence[MDP],
    seeds: Sequence[int],
    n_steps: int,
    *,
    log_period: int = 100,
    n_buckets: int = 4,
    work_dir: str | os.PathLike | None = None,
    progress: bool = False,
    run: Callable[..., runner.RunResult] = runner.run,
) -> tuple[np.ndarray, float, float]:
    """``(scores [C, N], run_s, compile_s)``: the final ``normalized_cumulative_regret`` of every candidate
    hyperparameter set on every ``mdps[j]``, whose agent is seeded with ``jax.random.key(seeds[j])``.

    One ``run`` call (:func:`jaxmdp.runner.run`) per size bucket of ``mdps``; with ``work_dir`` each call keeps a
    CSV and a checkpoint there, so an interrupted search resumes. ``progress``: a line per bucket on stderr and the
    runner's display, a bar on a terminal or a line every :data:`~jaxmdp.experiment.progress.LOG_EVERY_S` seconds
    in a log.
    """
    candidates = list(candidates)
    mdps = list(mdps)
    seeds = [int(s) for s in seeds]
    if not candidates or not mdps or len(seeds) != len(mdps):
        raise ValueError("candidates and mdps must be non-empty and seeds must hold one seed per MDP")
    C, N = len(candidates), len(mdps)
    scores = np.full((C, N), np.nan)
    run_s = compile_s = 0.0
    buckets = jaxmdp.size_buckets(mdps, n_buckets)
    for b, group in enumerate(buckets):
        members = [(c, j) for c in range(C) for j in range(len(group))]
        bucket = [mdps[g] for g in group]
        if progress:
            print(f" bucket {b + 1}/{len(buckets)}: {len(members)} members, up to "
                  f"{max(m.n_states for m in bucket)} states", file=sys.stderr, flush=True)
        fitted = hp_sources.fit_static_sizes(agent.name, candidates, bucket)
        hparams = runner.stack_hparams([fitted[c] for c, _ in members])
        member_seeds = [seeds[group[j]] for _, j in members]
        g = runner.grid(bucket, hparams, runner.seed_keys(member_seeds), mdp_index=[j for _, j in members],
                        hparams_index=[c for c, _ in members], seeds=member_seeds)
        paths = {}
        if work_dir is not None:
            Path(work_dir).mkdir(parents=True, exist_ok=True)
            paths = dict(csv_path=Path(work_dir) / f"{agent.name}-bucket{b}.csv",
                         checkpoint_path=Path(work_dir) / f"{agent.name}-bucket{b}.npz")
        with Progress(len(members) * n_steps, f"{agent.name}, bucket {b + 1}/{len(buckets)}", quiet=not progress,
                      log_every=LOG_EVERY_S) as display:
            result = run(agent, g, n_steps, log_period=log_period, progress=display, **paths)
        final = result.column("normalized_cumulative_regret")[-1]
        for i, (c, j) in enumerate(members):
            scores[c, group[j]] = final[i]
        run_s += result.run_s
        compile_s += result.compile_s
    return scores, run_s, compile_s


def check_tunable(name: str) -> None:
    """``ValueError`` unless the registered agent ``name`` can be searched here: it has a search space of uniform
    ranges (:data:`agents.search_spaces.SEARCH_SPACES`, given to :func:`agents.register` for your own) and observes
    the states or nothing (the search sets are tabular MDPs)."""
    agent = agent_registry.get(name)
    if name not in SEARCH_SPACES:
        raise ValueError(f"agent {name!r} has no search space of ranges to tune; register it with one: "
                         "agents.register(agent, search_space={field: (low, high), ...}); tunable: "
                         f"{', '.join(SEARCH_SPACES)}")
    if agent.observation == "emission":
        raise ValueError(f"agent {name!r} observes emissions; the search runs on the states of tabular MDPs")


def search(
    name: str,
    budget: Budget = Budget(),
    *,
    n_buckets: int = 4,
    work_dir: str | os.PathLike | None = None,
    progress: bool = False,
    run: Callable[..., runner.RunResult] = runner.run,
) -> SearchResult:
    """Random search for agent ``name`` on its setting's search set (module docstring)."""
    agent = agent_registry.get(name)
    values = hp_sources.reference_candidates(agent, budget.n_candidates, budget.search_seed)
    labels = [f"sample_{i}" for i in range(budget.n_candidates)]
    if budget.include_reference:
        default = agent.default_hparams
        values.append({f: float(getattr(default, f)) for f in search_space(agent)})
        labels.append("reference")
    candidates = [hp_sources.with_values(agent, v) for v in values]
    set_name = "search episodic" if agent.episodic else "search continuous"
    mdps, members, left_out = [], [], []
    for inst in sets.instances(set_name, n_per_family=budget.n_per_family, search_seed=budget.search_seed):
        built = [inst.build(s) for s in range(budget.n_seeds)]
        if budget.max_states is not None and max(m.n_states for m in built) > budget.max_states:
            left_out.append(inst.label)
            continue
        mdps += built
        members += [(inst.label, s) for s in range(budget.n_seeds)]
    if not mdps:
        raise ValueError(f"max_states={budget.max_states} leaves no MDP of the {set_name!r} set")
    scores, run_s, compile_s = evaluate(
        agent, candidates, mdps, [s for _, s in members], budget.n_steps, log_period=budget.log_period,
        n_buckets=n_buckets, work_dir=work_dir, progress=progress, run=run,
    )
    return SearchResult(name, labels, values, scores, members, left_out, run_s, compile_s)


def _commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent, capture_output=True, text=True,
                             check=True)
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def tuned_entry(name: str, budget: Budget, *, n_buckets: int, work_dir: Path, note: str = "",
                progress: bool = False) -> dict[str, Any]:
    """:func:`search` of one agent and its tuned-file entry (:func:`provenance`) with the search's wall seconds
    (``wall_s``): one agent's tuning, as the tuner runs it in its own process or as a Ray task."""
    start = time.perf_counter()
    result = search(name, budget, n_buckets=n_buckets, progress=progress, work_dir=work_dir)
    entry = provenance(result, budget, note=note)
    entry["wall_s"] = round(time.perf_counter() - start, 1)
    return entry


def provenance(result: SearchResult, budget: Budget, note: str = "") -> dict[str, Any]:
    """The tuned-file entry of a search: the winner's values, its objective, the budget and where it came from."""
    best = result.best
    obj = result.objective
    entry = {
        "values": result.values[best],
        "winner": result.labels[best],
        "objective": float(obj[best]),
        "objective_per_step": float(obj[best] / budget.n_steps),
        "candidates": [
            {"label": lab, "values": v, "objective": float(o)} for lab, v, o in zip(result.labels, result.values, obj)
        ],
        "budget": {**dataclasses.asdict(budget), "seeds": list(range(budget.n_seeds)),
                   "n_mdps": len({m for m, _ in result.members}), "left_out_mdps": result.left_out,
                   "reduced": budget.reduced},
        "run_s": round(result.run_s, 1),
        "compile_s": round(result.compile_s, 1),
        "commit": _commit(),
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "jax_backend": jax.default_backend(),
    }
    if note:
        entry["note"] = note
    return entry


def start_tuned_file(path: str | os.PathLike) -> None:
    """Start a tuned file at ``path`` as a copy of the entries of the shipped one
    (:data:`hardness.benchmark.hparams.TUNED_FILE`), so that with the entries a search adds it is a complete tuned
    file for ``run --hparams PATH``."""
    write_tuned(path, hp_sources.load_tuned())


def write_tuned(path: str | os.PathLike, entries: dict[str, dict]) -> None:
    """Merge ``entries`` (agent name -> :func:`provenance`) into the tuned file at ``path`` (other agents kept;
    its folder made if missing)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = json.loads(path.read_text()) if path.exists() else {}
    data.setdefault("format", 1)
    data["description"] = (
        "Tuned hyperparameters of the tabular agents (random search, hardness.benchmark.search; paper App. F). "
        "Each entry: the winning values, its objective (mean final normalized_cumulative_regret over the search "
        "MDPs and seeds), every candidate's objective, the budget and where it ran."
    )
    data.setdefault("agents", {}).update(entries)
    data["agents"] = dict(sorted(data["agents"].items()))
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    os.replace(tmp, path)
