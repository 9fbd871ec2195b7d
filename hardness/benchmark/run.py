"""The benchmark run (paper §3.3, App. G): every (MDP, agent, seed) of the chosen sets to completion, resumable.

Protocol (benchmark.md §2): every MDP of a set is run with every agent of the set's type for every seed; the same
integer seed builds the MDP and seeds the agent; indicators are logged every ``log_period`` steps; the score is the
final ``normalized_cumulative_regret`` divided by the steps. Unlike the reference, learning never stops: every run
completes its ``n_steps`` and the time it took is recorded (the reference stops learning after ten minutes of wall
clock).

Batches: the MDPs of a set are split into size buckets (:func:`jaxmdp.size_buckets` on each MDP's seed-0 instance, all
seeds of an MDP in its bucket; ``n_buckets`` of them, another count for the agents named in
:data:`PLANNING_BUCKETS` and :data:`DEEP_BUCKETS`), and
one batch is one agent on one bucket, at most ``max_members`` members (the
buckets' members split in order otherwise): one lockstep runner call (:func:`jaxmdp.runner.run`) in which no member
pays for a larger bucket's padding. Identical instances (seed-independent families) are stored once per batch. A
batch whose compiled programs would not fit in memory (the runner checks before running,
:mod:`jaxmdp.experiment.memory`) is split in halves until they fit (:func:`split_batch`; unless ``max_members`` is
given), each half padded like the whole batch so that its members' results are the same; ``part_members`` splits a
batch the same way into parts that each finish on their own.

Deep agents (paper §3.1, App. G): with ``emission`` every MDP is wrapped as a noiseless BlockMDP
(:func:`to_block_mdp`; the non-tabular benchmark's choice is ``StateInfo``), the default agents are the deep agents
of each set's type and the random agent (the baseline). A batch whose MDPs emit observations of different shapes
(``state_info`` of RiverSwim has one field, of DeepSea two) runs them zero-padded to one shape
(:func:`jaxmdp.pad_observations`; the deep agents initialise their input layers for the unpadded observations), so a
bucket is one batch and one compiled program per agent; only observations of different ranks go to separate batches.
The linear emissions' random features come from :func:`emission_key` of the member's seed.

Output folder:

* ``plan.json``: the settings and the batches of every call on the folder, merged (:mod:`hardness.benchmark.plans`:
  one protocol per folder; the batches a call shares with the folder are reused without building any MDP);
* ``runs/<batch>.csv``: the runner's per-record CSV of a batch (``member, mdp, hparams, seed`` and the reference's
  columns), written as it runs; ``runs/<batch>.ckpt.npz`` its checkpoint while it runs;
  ``runs/<batch>.json``: a finished batch's final values per member; ``runs/<batch>.curves.npz`` its curves;
* ``members.csv``: one row per finished (set, MDP, agent, seed): :data:`MEMBER_FIELDS`; rewritten after every batch
  in a fixed order, so an interrupted and resumed run ends with the same file byte for byte;
* ``batches.csv``: one row per finished batch: its members, compile and run seconds, step rates, and the host and pid
  that ran it (these cannot be reproduced byte for byte, so they live here rather than in ``members.csv``);
* the report (:mod:`hardness.benchmark.report`) once every batch has finished.

Resuming: a finished batch (its ``.json`` holds the same batch key: set, agent, members, steps, periods,
hyperparameters) is never run again; an interrupted one continues from its checkpoint. Results do not depend on where
a run was interrupted (the runner's keys are folded with the step index). Processes sharing a folder claim each batch
they run (``runs/<batch>.claim`` and ``.log``, :mod:`hardness.benchmark.claims`); ``shard`` runs a share of the
batches, and folders are merged, by :mod:`hardness.benchmark.shards`; ``ray`` hands the batches to Ray workers
(:mod:`hardness.benchmark.distributed`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import socket
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import agents as agent_registry
import jaxmdp
from filelock import FileLock

from hardness.benchmark import claims, plans, sets, shards
from hardness.benchmark import hparams as hp_sources
from jaxmdp import runner
from jaxmdp._checks import check_bool, check_variant
from jaxmdp.experiment.members import dynamics
from jaxmdp.experiment.progress import Progress
from jaxmdp.mdp import MDP
from hardness.benchmark.emissions import (  # noqa: F401 (re-exported: the run's public names)
    EMISSION_STREAM,
    KEYED_EMISSIONS,
    REFERENCE_EMISSIONS,
    canonical_emission,
    emission_key,
    observation_shape,
    to_block_mdp,
)
from hardness.benchmark.plans import Batch
from hardness.benchmark.tables import BATCH_FIELDS, MEMBER_FIELDS, _finished, _write_atomic, write_tables  # noqa: F401

__all__ = ["MEMBER_FIELDS", "BATCH_FIELDS", "QUICK", "PLANNING_BUCKETS", "DEEP_BUCKETS", "RunConfig", "Batch",
           "RunSummary", "default_agents", "quick_config", "plan", "batch_grid", "padded_blocks", "run_benchmark"]

#: The reference's quick-test protocol (benchmark.md §2: 2 seeds, indicators every 1000 / 500 steps); the steps are
#: fewer than its 50 000 so that ``--quick`` takes minutes on a CPU, and PSRL continuous is left out: its optimistic
#: planning (up to 60 sampled kernels per pair on the set's 160 padded states) costs more than the rest of the quick
#: run together (``--agents psrl_continuous`` runs it; docs/performance.md, Benchmark wall time).
QUICK = dict(sets=sets.QUICK_SETS, seeds=(0, 1), n_steps=1_000, n_buckets=1, agent_buckets={},
             agents=("q_learning_episodic", "psrl_episodic", "random_episodic", "q_learning_continuous", "ucrl2",
                     "random_continuous"),
             log_periods={"episodic quick test": 1000, "continuous quick test": 500})


#: Size buckets per set for the agents that run on more than :attr:`RunConfig.n_buckets`. Episodic PSRL draws a dense
#: ``[S, A, S]`` posterior at every episode, so a member padded to its bucket's ``S_b`` and ``A_b`` pays ``S_b^2 A_b``
#: per episode instead of ``S^2 A``, and the small MDPs with short horizons plan most often. Summed over each episodic
#: set's MDPs per episode (``sum S_b^2 A_b / H`` over ``sum S^2 A / H``), four buckets pad that work by 1.47 (ergodic)
#: and 1.64 (communicating), eight by 1.18 and 1.22, sixteen by 1.001 and 1.002: on a CPU, where a batch costs in
#: proportion to its members, sixteen buckets save about a sixth of episodic PSRL's draws (its floor, three quarters
#: of its time) for eight more compilations of about 10 s per set. PSRL continuous's plans cost as much on eight
#: buckets as on four (their cost sits in the largest buckets), so it and the other agents keep four: every batch is
#: one more compilation (and, on a GPU, where a lockstep step costs about the same whatever its members, one more
#: sequence of lockstep steps: pass fewer ``agent_buckets`` there). See docs/performance.md, Benchmark wall time.
PLANNING_BUCKETS: Mapping[str, int] = {"psrl_episodic": 16}

#: Size buckets per set for the deep agents: two programs per agent and setting. A member padded to its bucket's
#: states pays for them at every log (the greedy policy of the network on every state, its exact regret), and every
#: batch pays its own compiling and lockstep loop: on the continuous ergodic set one bucket runs DQN 2x slower than
#: two, four run 1.1x slower and compile 1.6x longer (docs/performance.md, Deep agents).
DEEP_BUCKETS: Mapping[str, int] = {
    n: 2 for n in agent_registry.names(observations=("emission",)) if n in agent_registry.SHIPPED}


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """What to run.

    Attributes:
      sets: names of :mod:`hardness.benchmark.sets` sets.
      agents: registry names; ``None``: :func:`default_agents` of each set. Each agent runs on the sets of its type.
      seeds, n_steps: seeds (each builds the MDP and seeds the agent) and steps of every run.
      log_period: steps between indicator logs, unless ``log_periods`` names the set.
      hparams: ``"tuned"``, ``"reference"`` or a tuned-file path (:func:`hardness.benchmark.hparams.hparams_for`).
      n_buckets: size buckets per set; max_members: members per runner call (``None``: a whole bucket, halved
        until its programs fit in memory, :func:`split_batch`).
      agent_buckets: size buckets per set for the agents it names, instead of ``n_buckets`` (default
        :data:`PLANNING_BUCKETS` and :data:`DEEP_BUCKETS`). A member's results depend on its bucket (its padding
        shapes the random draws).
      memory_limit: bytes a runner call's programs may use (``None``: what the machine has available); not part of
        the results, so not of the plan's settings.
      part_members: run a batch of more members in parts of at most this many (:func:`split_batch`'s halves, again
        until each is small enough), each finished and written on its own, so that a batch of hours becomes pieces
        that a machine finishes within its lifetime and a later call resumes from what was written; a batch with a
        checkpoint continues whole. ``None``: whole batches. Not part of the results (a part is padded like its
        batch), so not of the plan's settings.
      n_records: records per member in the per-record CSVs and curves.
      emission: the emission through which the agents observe the MDPs (:func:`to_block_mdp`: a kind of
        :data:`jaxmdp.EMISSION_KINDS` or a reference class name such as ``"StateInfo"``); the deep agents need one,
        the tabular agents refuse one, the random agent runs either way (``None``: the agents observe the states).
      only: keep only the MDPs with these labels (``"RiverSwim/prms_0"``) or families (``None``: every MDP).
      agent_variant: ``"paper"`` (the algorithms as published) or ``"colosseum"`` (reference mode: the tabular agents
        with the reference's update rules, :func:`agents.get`); with ``hparams="reference"`` the like-for-like
        counterpart of the paper's published numbers.
      indicator_variant: the regret indicators (:mod:`jaxmdp.experiment.indicators`): ``"paper"`` (exact expected
        regret from the start distribution, gain-optimal ``rho*``; the default) or ``"colosseum"`` (the reference's:
        the episodic regret at the last episode's start, ``rho*`` of the 0.99-discounted greedy policy, regrets up to
        ``1e-3`` zeroed; docs/measures.md §6). With ``agent_variant="colosseum"`` and ``hparams="reference"``, the
        reference's pipeline but for its random streams, its policy estimates' ties and its cut-offs.
      stop_when_converged: the reference's convergence stop (:func:`jaxmdp.runner.run`; docs/measures.md §6.4): a
        member whose normalised regret stayed near 0 for ten logs past a fifth of the run stops learning. Off by
        default (the paper's protocol learns to the end); with reference mode, the reference's loop.
    """

    sets: tuple[str, ...]
    agents: tuple[str, ...] | None = None
    seeds: tuple[int, ...] = tuple(range(20))
    n_steps: int = 500_000
    log_period: int = 100
    log_periods: Mapping[str, int] = dataclasses.field(default_factory=dict)
    hparams: str = "tuned"
    n_buckets: int = 4
    agent_buckets: Mapping[str, int] = dataclasses.field(
        default_factory=lambda: {**PLANNING_BUCKETS, **DEEP_BUCKETS})
    max_members: int | None = None
    n_records: int = 100
    emission: str | None = None
    only: tuple[str, ...] | None = None
    agent_variant: str = "paper"
    memory_limit: int | None = None
    indicator_variant: str = "paper"
    stop_when_converged: bool = False
    part_members: int | None = None

    def period(self, set_name: str) -> int:
        return int(self.log_periods.get(set_name, self.log_period))

    def buckets(self, agent: str) -> int:
        """Size buckets per set for ``agent``."""
        return int(self.agent_buckets.get(agent, self.n_buckets))


@dataclasses.dataclass
class RunSummary:
    """What a call did: batches run (or continued), batches already finished, whether every batch of the call (of its
    shard) is finished."""

    ran: list[str]
    reused: list[str]
    finished: bool
    out: Path
    #: Batches of the call that other processes finished while it ran (:mod:`hardness.benchmark.claims`).
    others: list[str] = dataclasses.field(default_factory=list)


def default_agents(set_name: str, emission: str | None = None) -> list[str]:
    """Every shipped agent of the set's type that observes what the run hands out (without ``emission``: the
    tabular agents; with one: the deep agents), the learning agents first (registry order), the random agent (which
    runs on both, the baseline) last. Agents added with :func:`agents.register` run when named."""
    episodic = sets.is_episodic(set_name)
    wanted = ("state", "any") if emission is None else ("emission", "any")
    names = [n for n in agent_registry.names(episodic=episodic, observations=wanted) if n in agent_registry.SHIPPED]
    return [n for n in names if not n.startswith("random")] + [n for n in names if n.startswith("random")]


def quick_config(**overrides: Any) -> RunConfig:
    """The ``--quick`` settings (:data:`QUICK`), with ``overrides``."""
    return RunConfig(**{**QUICK, **overrides})


def _agents_of(config: RunConfig, set_name: str) -> list[str]:
    episodic = sets.is_episodic(set_name)
    if config.agents is None:
        return default_agents(set_name, config.emission)
    return [n for n in config.agents if agent_registry.get(n).episodic == episodic]


def _check(config: RunConfig) -> list[str]:
    """Validate ``config``; returns the canonical set names."""
    names = [sets.canonical_name(s) for s in config.sets]
    if not names:
        raise ValueError("sets must name at least one benchmark set")
    if config.emission is not None:
        canonical_emission(config.emission)
    if config.emission is not None and config.agent_variant != "paper":
        raise ValueError("agent_variant 'colosseum' (reference mode) exists for the tabular agents only, not with an "
                         "emission")
    check_variant(config.agent_variant, "agent_variant")
    check_variant(config.indicator_variant, "indicator_variant")
    check_bool("stop_when_converged", config.stop_when_converged)
    for name in config.agents or ():
        agent = agent_registry.get(name, config.agent_variant)
        if not any(sets.is_episodic(s) == agent.episodic for s in names):
            raise ValueError(f"agent {name!r} is {'episodic' if agent.episodic else 'continuous'} but no set of "
                             f"{names} is; choose a set of its type")
        if agent.observation == "emission" and config.emission is None:
            raise ValueError(f"agent {name!r} observes emissions: pass --emission (e.g. StateInfo)")
        if agent.observation == "state" and config.emission is not None:
            raise ValueError(f"agent {name!r} is tabular; --emission is for agents that observe emissions")
    if not config.seeds or any(int(s) < 0 for s in config.seeds) or len(set(config.seeds)) != len(config.seeds):
        raise ValueError(f"seeds must be distinct non-negative integers; got {config.seeds}")
    for field in ("n_steps", "log_period", "n_buckets", "n_records"):
        value = getattr(config, field)
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{field} must be a positive integer; got {value!r}")
    for agent, count in config.agent_buckets.items():
        if agent not in agent_registry.AGENTS:
            raise ValueError(f"agent_buckets names an unknown agent {agent!r}; known: {sorted(agent_registry.AGENTS)}")
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
            raise ValueError(f"agent_buckets[{agent!r}] must be a positive integer; got {count!r}")
    if config.max_members is not None and config.max_members < 1:
        raise ValueError(f"max_members must be a positive integer or None; got {config.max_members!r}")
    if config.memory_limit is not None and (isinstance(config.memory_limit, bool) or config.memory_limit < 1):
        raise ValueError(f"memory_limit must be a positive number of bytes or None; got {config.memory_limit!r}")
    parts = config.part_members
    if parts is not None and (isinstance(parts, bool) or not isinstance(parts, (int, np.integer)) or parts < 1):
        raise ValueError(f"part_members must be a positive integer (members per part of a batch) or None; got "
                         f"{parts!r}")
    # Named agents run on the sets of their type only: a set that none of them is for is left out (--quick with
    # episodic agents runs the episodic quick-test set).
    return [s for s in names if config.agents is None or _agents_of(config, s)]


def _hparams_repr(hp: Any) -> dict[str, str]:
    return {f.name: repr(np.asarray(getattr(hp, f.name)).tolist()) for f in dataclasses.fields(hp)}


def _settings(config: RunConfig, names: Sequence[str]) -> dict[str, Any]:
    """Everything a plan depends on (JSON), the agents' resolved hyperparameters included."""
    agents_by_set = {s: _agents_of(config, s) for s in names}
    all_agents = list(dict.fromkeys(a for s in names for a in agents_by_set[s]))
    # Named only when on, so that the plans and batch keys of runs without it stay what they were.
    stop = {"stop_when_converged": True} if config.stop_when_converged else {}
    return dict(
        sets=list(names), agents=agents_by_set, seeds=[int(s) for s in config.seeds], n_steps=int(config.n_steps),
        log_periods={s: config.period(s) for s in names}, hparams_source=str(config.hparams),
        hparams={a: _hparams_repr(hp_sources.hparams_for(a, config.hparams, config.agent_variant))
                 for a in all_agents},
        agent_variant=config.agent_variant,
        n_buckets=int(config.n_buckets), max_members=config.max_members, n_records=int(config.n_records),
        agent_buckets={a: config.buckets(a) for a in all_agents if config.buckets(a) != config.n_buckets},
        emission=None if config.emission is None else canonical_emission(config.emission),
        # Named only with an emission: a folder of an emission run from before the padding refuses this protocol.
        **({} if config.emission is None else {"observations": "padded"}),
        variant=config.indicator_variant,
        only=list(config.only) if config.only else None, **stop,
    )


def _slug(text: str) -> str:
    return text.replace(" ", "_").replace("/", "-")


def plan(config: RunConfig, out: str | os.PathLike | None = None) -> tuple[dict[str, Any], list[Batch]]:
    """``(settings, batches)`` of ``config`` (module docstring). With ``out``, the plan is merged into the folder's
    ``plan.json`` (:mod:`hardness.benchmark.plans`: ``ValueError`` when the folder holds another protocol): the
    batches of the (set, agent) pairs that the folder already plans are taken from there (no MDP is built for them;
    batches split to fit in memory stay split)."""
    settings, batches = _plan(config, out)
    if out is not None:
        batches = plans.commit_call(Path(out), settings, batches)
    return settings, batches


def _plan(config: RunConfig, out: str | os.PathLike | None) -> tuple[dict[str, Any], list[Batch]]:
    """:func:`plan` without writing anything."""
    names = _check(config)
    settings = _settings(config, names)
    folder = plans.load(out) if out is not None else None
    known: dict[tuple[str, str], list[Batch]] = {}
    if folder is not None:
        plans.merge_settings(folder["settings"], settings, str(out))  # refuse another protocol before building
        for b in folder["batches"]:
            known.setdefault((b["set_name"], b["agent"]), []).append(plans.to_batch(b))
    batches = []
    for set_name in names:
        need = [a for a in settings["agents"][set_name] if (set_name, a) not in known]
        built = _set_batches(config, settings, set_name, need) if need else {}
        for agent in settings["agents"][set_name]:
            batches += known.get((set_name, agent)) or built[agent]
    return settings, batches


def _set_batches(config: RunConfig, settings: dict, set_name: str, agents: Sequence[str]) -> dict[str, list[Batch]]:
    """The batches of ``agents`` on ``set_name``: per agent, its size buckets in order (module docstring)."""
    found = [i for i in sets.instances(set_name) if not config.only or {i.label, i.family} & set(config.only)]
    if not found:
        raise ValueError(f"only={list(config.only or ())} keeps no MDP of the {set_name!r} set")
    sizes = [inst.build(config.seeds[0]) for inst in found]
    grouped = {}
    for n_buckets in sorted({config.buckets(a) for a in agents}):
        groups = [(f"b{b}", sorted(g)) for b, g in enumerate(jaxmdp.size_buckets(sizes, n_buckets))]
        if settings["emission"] is not None:
            groups = _split_by_rank(groups, sizes, settings["emission"], config.seeds[0])
        grouped[n_buckets] = groups
    out: dict[str, list[Batch]] = {}
    for agent in agents:
        out[agent] = []
        for gid, group in grouped[config.buckets(agent)]:
            members = [(found[i].label, int(s)) for i in group for s in config.seeds]
            step = config.max_members or len(members)
            parts = [members[k : k + step] for k in range(0, len(members), step)]
            for p, part in enumerate(parts):
                bid = f"{_slug(set_name)}.{agent}.{gid}" + (f".p{p}" if len(parts) > 1 else "")
                out[agent].append(Batch(bid, _batch_key(settings, set_name, agent, part), set_name, agent,
                                        tuple(part)))
    return out


def _batch_key(settings: dict, set_name: str, agent: str, members: Sequence, whole: Sequence | None = None) -> str:
    """Hash of everything a batch's results depend on (a part's key includes the batch it was split from)."""
    key = {k: settings[k] for k in ("n_steps", "n_records", "emission", "observations", "variant", "agent_variant",
                                    "stop_when_converged") if k in settings}
    key.update(set=set_name, agent=agent, members=[list(m) for m in members],
               log_period=settings["log_periods"][set_name], hparams=settings["hparams"][agent])
    if whole is not None:
        key.update(whole=[list(m) for m in whole])
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]


def split_batch(batch: Batch, settings: dict) -> list[Batch]:
    """``batch`` in two halves (ids ``<id>.s0``, ``<id>.s1``): how :func:`run_benchmark` splits a batch whose
    programs do not fit in memory, or of more than ``part_members`` members. Each half remembers the batch it came
    from (:attr:`Batch.whole`, the original one after repeated splits) and is padded and sized like it (MDP shapes,
    PSRL's candidate buffer), so every member computes what it would have computed in the whole batch: the results
    do not depend on the machine's memory. (With an emission the halves' MDPs are padded to their own members and
    their observations to the whole batch's shape: the same trajectories and regrets, and the normalised columns,
    whose normalising gains are computed on the part's padded MDPs, the same to float32 rounding.)"""
    if len(batch.members) < 2:
        raise ValueError(f"batch {batch.id} has a single member and cannot be split")
    half = -(-len(batch.members) // 2)
    whole = batch.members if batch.whole is None else batch.whole
    return [
        Batch(f"{batch.id}.s{j}", _batch_key(settings, batch.set_name, batch.agent, part, whole), batch.set_name,
              batch.agent, tuple(part), whole)
        for j, part in enumerate((batch.members[:half], batch.members[half:]))
    ]


def _split_by_rank(
    groups: list[tuple[str, list[int]]], mdps: Sequence[MDP], emission: str, seed: int
) -> list[tuple[str, list[int]]]:
    """Split every size bucket into groups whose observations have one rank (observations of one rank are padded to
    one shape, :func:`batch_grid`; of different ranks they cannot share a runner call), named ``b<k>.o<j>`` when a
    bucket splits."""
    if emission == "one_hot":
        return groups
    out = []
    for gid, group in groups:
        shapes: dict[int, list[int]] = {}
        for i in group:
            shapes.setdefault(len(observation_shape(mdps[i], emission, seed)), []).append(i)
        parts = list(shapes.values())
        out += [(gid if len(parts) == 1 else f"{gid}.o{j}", part) for j, part in enumerate(parts)]
    return out


def _content_hash(m: MDP) -> str:
    h = hashlib.sha256()
    for x in (m.T, m.R, m.P0, m.reward_mean, m.reward_conc):
        h.update(np.ascontiguousarray(np.asarray(x)).tobytes())
    return h.hexdigest()


def _distinct(members: Sequence[tuple[str, int]], set_name: str, emission: str | None):
    """``(distinct MDPs, their labels, member -> distinct index, emission seed of each distinct MDP)``."""
    by_label = {i.label: i for i in sets.instances(set_name)}
    distinct: list[MDP] = []
    labels: list[str] = []
    index: dict[tuple[str, int], int] = {}
    mdp_index = []
    emission_seeds = []  # the seed whose emission key a distinct member's features come from
    for label, seed in members:
        m = by_label[label].build(seed)
        h = (_content_hash(m), seed if emission in KEYED_EMISSIONS else 0)  # keyed features differ per seed
        if h not in index:
            index[h] = len(distinct)
            distinct.append(m)
            labels.append(f"{label}@{seed}")
            emission_seeds.append(seed)
        mdp_index.append(index[h])
    return distinct, labels, mdp_index, emission_seeds


def batch_grid(batch: Batch, config: RunConfig) -> runner.Grid:
    """The runner grid of one batch of :func:`plan`, as :func:`run_benchmark` runs it (also for timing or inspecting a
    batch outside a run): each distinct instance once, labelled by its MDP label (and seed where it matters), with
    ``config``'s hyperparameters of the batch's agent; a part of a split batch padded and sized like the whole
    (:func:`split_batch`)."""
    hp = hp_sources.hparams_for(batch.agent, config.hparams, config.agent_variant)
    emission = None if config.emission is None else canonical_emission(config.emission)
    distinct, labels, mdp_index, emission_seeds = _distinct(batch.members, batch.set_name, emission)
    like = distinct
    if batch.whole is not None:
        like, _, _, like_seeds = _distinct(batch.whole, batch.set_name, emission)
        if emission is None:
            S, A, K = (max(getattr(m, f) for m in like) for f in ("n_states", "n_actions", "max_successors"))
            H = max(m.H for m in like) if like[0].episodic else None
            starts = max(m.max_starts for m in like)
            distinct = [jaxmdp.pad(m, S, A, K, H, starts) for m in distinct]
    fitted = hp_sources.fit_static_sizes(batch.agent, [hp], like)[0]
    seeds = [s for _, s in batch.members]
    hparams = runner.stack_hparams([fitted] * len(seeds))
    mdps = distinct if emission is None else padded_blocks(
        [to_block_mdp(m, emission, s) for m, s in zip(distinct, emission_seeds)],
        None if batch.whole is None else [observation_shape(m, emission, s) for m, s in zip(like, like_seeds)],
    )
    g = runner.grid(mdps, hparams, runner.seed_keys(seeds), mdp_index=mdp_index,
                    hparams_index=[0] * len(seeds), seeds=seeds)
    return dataclasses.replace(g, mdp_labels=tuple(labels))


def padded_blocks(blocks: Sequence[jaxmdp.BlockMDP], shapes: Sequence[tuple[int, ...]] | None = None
                  ) -> list[jaxmdp.BlockMDP]:
    """``blocks`` with their observations zero-padded (:func:`jaxmdp.pad_observations`) to the largest of ``shapes``
    (default: the blocks' own) on every axis, so that they stack into one batch; noiseless one-hot blocks as they are
    (:func:`jaxmdp.stack` pads them with their states)."""
    shapes = [b.obs_shape for b in blocks] if shapes is None else list(shapes)
    if blocks[0].emission_kind == "one_hot" or len(set(shapes)) == 1:
        return list(blocks)
    shape = tuple(int(n) for n in np.max(shapes, axis=0))
    return [jaxmdp.pad_observations(b, shape) for b in blocks]


def _finals(batch: Batch, result: runner.RunResult) -> list[dict[str, Any]]:
    n = float(result.n_steps)
    cols = {c: result.column(c)[-1] for c in (
        "cumulative_regret", "normalized_cumulative_regret", "normalized_cumulative_reward",
        "normalized_cumulative_expected_reward", "random_normalized_cumulative_regret")}
    family = {i.label: i.family for i in sets.instances(batch.set_name)}
    out = []
    for b, (label, seed) in enumerate(batch.members):
        out.append(dict(
            mdp=label, family=family[label], seed=int(seed), steps=int(result.steps[-1]),
            cumulative_regret=float(cols["cumulative_regret"][b]),
            normalized_cumulative_regret=float(cols["normalized_cumulative_regret"][b]),
            normalized_regret_per_step=float(cols["normalized_cumulative_regret"][b] / n),
            normalized_cumulative_reward=float(cols["normalized_cumulative_reward"][b]),
            normalized_cumulative_expected_reward=float(cols["normalized_cumulative_expected_reward"][b]),
            random_normalized_regret_per_step=float(cols["random_normalized_cumulative_regret"][b] / n),
        ))
    return out


def _run_batch(
    batch: Batch, config: RunConfig, run_dir: Path, stop_after_chunks: int | None, bar: Progress | bool = False
) -> bool:
    """Run (or continue from its checkpoint) one batch, stopping after ``stop_after_chunks`` runner chunks if given,
    the runner advancing ``bar`` by the member-steps of each chunk; returns whether it finished."""
    agent = agent_registry.get(batch.agent, config.agent_variant)
    g = batch_grid(batch, config)
    period = config.period(batch.set_name)
    # One runner call per batch: each call recomputes the members' indicator constants, which is not free.
    result = runner.run(agent, g, config.n_steps, log_period=period, n_records=config.n_records,
                        variant=config.indicator_variant, stop_when_converged=config.stop_when_converged,
                        csv_path=run_dir / f"{batch.id}.csv", checkpoint_path=run_dir / f"{batch.id}.ckpt.npz",
                        stop_after_chunks=stop_after_chunks, memory_limit=config.memory_limit, progress=bar)
    done = int(result.steps[-1]) if result.steps.size else 0
    if done < config.n_steps:
        return False
    compile_s = result.compile_s
    mdps = dynamics(g.mdps)  # a BlockMDP batch's MDPs
    states = int(np.asarray(mdps.state_mask).sum(axis=1).max())
    record = dict(
        key=batch.key, batch=batch.id, set=batch.set_name, agent=batch.agent, n_steps=config.n_steps,
        members=_finals(batch, result), n_members=g.n_members, n_mdps=int(mdps.T.shape[0]), max_states=states,
        compile_s=compile_s, run_s=result.run_s, host=socket.gethostname(), pid=os.getpid(),
    )
    curves = {c: result.column(c).astype(np.float32) for c in ("cumulative_regret", "random_cumulative_regret")}
    tmp = run_dir / f"{batch.id}.curves.tmp.npz"
    np.savez(tmp, steps=result.steps, **curves)
    os.replace(tmp, run_dir / f"{batch.id}.curves.npz")
    _write_atomic(run_dir / f"{batch.id}.json", json.dumps(record) + "\n")
    (run_dir / f"{batch.id}.ckpt.npz").unlink(missing_ok=True)
    return True


def run_benchmark(
    config: RunConfig,
    out: str | os.PathLike,
    *,
    progress: bool = True,
    log_every: float | None = None,
    report: bool = True,
    stop_at: tuple[int, int] | None = None,
    baseline: str | os.PathLike | None = None,
    shard: tuple[int, int] | None = None,
    poll_s: float = 2.0,
    heartbeat_s: float = claims.HEARTBEAT_S,
    stale_s: float = claims.STALE_S,
    ray: Any = None,
) -> RunSummary:
    """Run every batch of ``config`` that is not finished in ``out`` (module docstring), then write the report.

    Several processes may share ``out`` (:mod:`hardness.benchmark.claims`): each batch is claimed by the process that
    runs it; a process skips the batches that others hold, runs the rest, then polls every ``poll_s`` seconds until
    the others' batches have finished (taking over those whose holder is gone: ``heartbeat_s``, ``stale_s``).
    ``shard = (i, N)`` runs only shard ``i``'s share of the batches (:func:`hardness.benchmark.shards.share`); the
    report is written once every batch of the plan has finished in ``out``.
    ``baseline``: results set beside the run's own in the report (``"committed"``, the shipped agents' committed
    results, or a run folder; :mod:`hardness.benchmark.baselines`), checked before anything runs: ``ValueError``
    naming what differs when none of them was made under this run's protocol.
    ``log_every``: with ``progress`` and a stream that is not a terminal (a log file), a progress line at most every
    ``log_every`` seconds (:class:`~jaxmdp.experiment.progress.Progress`); ``None``: none.
    ``stop_at = (b, c)`` interrupts deterministically (for tests): after ``b`` batches of this call have finished, run
    ``c`` runner chunks of the next one and stop; the next call continues from there.
    ``ray``: run the batches as Ray tasks (:mod:`hardness.benchmark.distributed`: ``True``, a local instance; a
    cluster's address; or :class:`~hardness.benchmark.distributed.RayOptions`); ``None``: here, one after another.
    """
    out = Path(out)
    if shard is not None:
        shard = shards.check_shard(shard)
    if not poll_s > 0:
        raise ValueError(f"poll_s must be a positive number of seconds; got {poll_s!r}")
    if ray is not None and config.part_members is not None:
        raise ValueError("part_members applies to a run here, not to one on Ray (a Ray task retried on another "
                         "machine continues from its batch's checkpoint); got both")
    settings, batches = _plan(config, out)  # a refused run writes nothing
    if baseline is not None:
        from hardness.benchmark import baselines

        planned = {label for b in batches for label, _ in b.members}
        baselines.select(settings, {s: [i.label for i in sets.instances(s) if i.label in planned]
                                    for s in settings["sets"]}, baseline)
    run_dir = out / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    view = plans.CallView(out, settings, plans.commit_call(out, settings, batches))
    mine = view.share(shard)
    done = {b.id for b in mine if _finished(run_dir, b) is not None}
    reused = [b.id for b in mine if b.id in done]
    ran: list[str] = []
    others: list[str] = []
    finished = True
    total = sum(len(b.members) for b in mine if b.id not in done) * config.n_steps
    # One bar of member-steps over every batch of this call, advanced by the runner after each of its chunks (so it
    # moves inside a batch of hours) and by the batches other processes finish; on a terminal, or as lines in a log.
    with Progress(total, "benchmark", quiet=not progress or not total, log_every=log_every) as bar, claims.Claims(
        out, heartbeat_s=heartbeat_s, stale_s=stale_s
    ) as held:
        if ray is not None:  # the batches as Ray tasks
            from hardness.benchmark import distributed

            distributed.run_batches(config, settings, view, shard, bar, held, done, ran, others, ray, poll_s=poll_s,
                                    stop_at=stop_at)
        k = 0
        while ray is None:
            mine = view.share(shard)
            for b in mine:  # batches that other processes finished
                if b.id not in done and _finished(run_dir, b) is not None:
                    done.add(b.id)
                    others.append(b.id)
                    bar.update(len(b.members) * config.n_steps)
            todo = [b for b in mine if b.id not in done]
            if not todo:
                break
            batch = next((b for b in todo if held.take(b.id)), None)
            if batch is None:  # every batch left is another process's: wait for it, or for its holder to go
                bar.set_postfix(f"waiting for {len(todo)} batches of other processes")
                time.sleep(poll_s)
                continue
            if _finished(run_dir, batch) is not None:  # finished between the look and the claim
                held.drop(batch.id)
                continue
            if (config.part_members is not None and len(batch.members) > config.part_members
                    and not (run_dir / f"{batch.id}.ckpt.npz").exists()):
                # The plan first, then the claim: no other process can take the whole batch in between.
                plans.replace(out, dataclasses.asdict(batch), [dataclasses.asdict(h)
                                                               for h in split_batch(batch, settings)])
                held.drop(batch.id, f"split: parts of at most {config.part_members} members")
                continue
            bar.set_postfix(f"{batch.id}: {len(batch.members)} members")
            chunks = stop_at[1] if stop_at is not None and k == stop_at[0] else None
            try:
                complete = _run_batch(batch, config, run_dir, chunks, bar)
            except runner.ProgramTooLarge as err:
                held.drop(batch.id, "split: does not fit in memory")
                if config.max_members is not None or len(batch.members) < 2:
                    raise
                halves = split_batch(batch, settings)
                bar.write(f"{batch.id} does not fit in memory ({err}); split into {len(halves)} parts", log=True)
                plans.replace(out, dataclasses.asdict(batch), [dataclasses.asdict(h) for h in halves])
                continue
            except BaseException as err:
                held.drop(batch.id, f"failed: {type(err).__name__}")
                raise
            held.drop(batch.id, "finished" if complete else "stopped")
            ran.append(batch.id)
            if not complete:
                finished = False
                break
            k += 1
            done.add(batch.id)
            plans.write_folder_tables(out)
    n_rows = plans.write_folder_tables(out)
    whole = view.share(None)  # every shard's batches
    complete = finished and all(b.id in done or _finished(run_dir, b) is not None for b in whole)
    if shard is not None and finished and not complete and progress:
        print(f"shard {shard[0]}/{shard[1]} finished in {out}; once every shard has, merge the folders: "
              "jaxmdp-benchmark report DIR1 DIR2 ... --out DIR", file=sys.stderr)
    if complete and report and (ran or others or baseline is not None or not (out / "report.md").exists()):
        from hardness.benchmark import report as report_module

        t0 = time.perf_counter()
        with FileLock(str(out / "report.lock")):  # one process writes the report at a time
            report_module.write_report(out, baseline)
        if progress:
            print(f"report written to {out} ({n_rows} members, {time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    return RunSummary(ran=ran, reused=reused, finished=finished, out=out, others=others)
