"""Normalised cumulative regret of the deep agents beside the random agent's, on small BlockMDPs (paper §3.1, App. G).

Every deep agent of an instance's setting (``dqn``, ``boot_dqn``, ``actor_critic``, ``actor_critic_rnn``, episodic or
continuous) and the random agent run on the noiseless ``state_info`` BlockMDP (``jaxmdp.block_mdp(mdp,
"state_info")``, the paper's non-tabular benchmark emission) of each instance, for ``--steps`` steps and ``--seeds``
seeds (0, 1, ...), at their default hyperparameters (bsuite's own; the reference ships no tuned values for them,
docs/agents.md §7). One (instance, agent) pair is one :func:`jaxmdp.experiment.runner.run` call over the seeds.

Score (the paper's Table 2 number, App. E): the final ``normalized_cumulative_regret`` divided by the steps, 0 for an
optimal agent and 1 for the worst policy; the table gives its mean ± standard deviation over seeds (``ddof = 1``).
Indicators are exact policy evaluations of the greedy policy of the network on every row of the emission table,
every ``--log-period`` steps. An agent is *below random* when its mean is below the random agent's mean, and *below
on every seed* when its worst seed is below the random agent's best.

Instances (``--instances``, ``Family-size-setting`` items; every one built with seed 0, the agents' seeds varying):

* ``RiverSwim-6-continuous``: ``p_lazy = 0.1``, ``p_rand = 0.01``, Beta rewards, actions not permuted (the
  episodic-ergodic benchmark's RiverSwim ``prms_0`` at size 6);
* ``DeepSea-6-episodic``: no ``p_rand``, Beta rewards, actions not permuted (the episodic-communicating benchmark's
  DeepSea ``prms_0`` at size 6; DeepSea is bsuite's episodic deep-exploration probe);
* ``SimpleGrid-4-episodic`` and ``SimpleGrid-4-continuous``: ``p_lazy = 0.2``, ``p_rand = 0.01``, Beta rewards,
  actions not permuted (the episodic-ergodic benchmark's SimpleGrid ``prms_0`` at size 4).

Output in ``--out`` (default ``results/deep_agents_regret``), written as it goes:

* ``rows.csv``: one row per finished (instance, agent): :data:`ROW_FIELDS` (the per-seed scores among them), appended
  when the pair finishes; an invocation skips the pairs whose row has the same settings (``settings`` column);
* ``runs/<instance>.<agent>.<settings>.csv`` / ``.npz``: the runner's per-record CSV and its checkpoint while the
  pair runs, so an interrupted pair continues where it stopped;
* ``deep_agents_regret.md``: the table, rewritten after every pair.

The cheap agents run first and BootDQN (a 20-head ensemble trained on a batch of 128 at every step) last.

    jaxmdp-regret-table --deep                        # 50 000 steps, 4 seeds
    jaxmdp-regret-table --deep --instances DeepSea-6-episodic --agents dqn_episodic
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import json
import os
import platform
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np

import agents
import jaxmdp
from jaxmdp.experiment import records, runner

#: The emission of every instance (the reference's non-tabular benchmark: ``StateInfo``).
EMISSION = "state_info"

#: The families' parameters besides ``size`` (module docstring).
FAMILY_PARAMS: dict[str, dict[str, Any]] = {
    "RiverSwim": dict(p_lazy=0.1, p_rand=0.01, make_reward_stochastic=True, randomize_actions=False),
    "DeepSea": dict(p_rand=None, make_reward_stochastic=True, randomize_actions=False),
    "SimpleGrid": dict(p_lazy=0.2, p_rand=0.01, make_reward_stochastic=True, randomize_actions=False),
}

DEFAULT_INSTANCES = ("RiverSwim-6-continuous", "DeepSea-6-episodic", "SimpleGrid-4-episodic",
                     "SimpleGrid-4-continuous")

#: Columns of ``rows.csv``. ``per_seed``: the seeds' scores, space separated, in seed order;
#: ``agent_steps_per_s``: steps of all seeds per second of the lockstep loop (compilation excluded).
ROW_FIELDS = (
    "instance", "setting", "agent", "n_seeds", "n_steps", "regret_per_step_mean", "regret_per_step_std", "per_seed",
    "random_baseline", "compile_s", "run_s", "agent_steps_per_s", "settings",
)


@dataclasses.dataclass(frozen=True)
class Instance:
    """A ``Family-size-setting`` instance (module docstring)."""

    family: str
    size: int
    episodic: bool

    @property
    def name(self) -> str:
        return f"{self.family}-{self.size}-{'episodic' if self.episodic else 'continuous'}"

    def build(self) -> jaxmdp.BlockMDP:
        """The instance (seed 0) through the :data:`EMISSION` emission, without noise."""
        mdp = jaxmdp.make(self.family, episodic=self.episodic, seed=0, size=self.size, **FAMILY_PARAMS[self.family])
        return jaxmdp.block_mdp(mdp, EMISSION)


def parse_instance(text: str) -> Instance:
    """``"RiverSwim-6-continuous"`` as an :class:`Instance`; ``ValueError`` naming what is allowed otherwise."""
    family, _, rest = str(text).partition("-")
    size, _, setting = rest.partition("-")
    if family not in FAMILY_PARAMS or not size.isdigit() or int(size) < 2 or setting not in ("episodic", "continuous"):
        raise ValueError(f"instances must be Family-size-setting items with Family in {sorted(FAMILY_PARAMS)}, size "
                         f">= 2 and setting 'episodic' or 'continuous' (e.g. 'RiverSwim-6-continuous'); got {text!r}")
    return Instance(family, int(size), setting == "episodic")


def agents_of(episodic: bool) -> list[str]:
    """The registered deep agents of the setting (registry order), then the random agent."""
    deep = [n for n, a in agents.AGENTS.items() if a.observation == "emission" and a.episodic == episodic]
    return deep + ["random_episodic" if episodic else "random_continuous"]


def settings_key(n_steps: int, n_seeds: int, log_period: int) -> str:
    """A short hash of what a row depends on besides its instance and agent (stored in the ``settings`` column)."""
    text = json.dumps(dict(n_steps=n_steps, n_seeds=n_seeds, log_period=log_period, emission=EMISSION,
                           params=FAMILY_PARAMS, variant="paper"), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def read_rows(path: Path) -> list[dict[str, str]]:
    """The rows of ``rows.csv`` (none if it does not exist)."""
    if not path.exists():
        return []
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def _append_row(path: Path, row: dict[str, Any]) -> None:
    new = not path.exists()
    with path.open("a", newline="") as f:
        w = csv.writer(f)
        if new:
            w.writerow(ROW_FIELDS)
        w.writerow(records.format_row([row[c] for c in ROW_FIELDS]))


def run_stem(instance: Instance, agent_name: str, key: str) -> str:
    """The file stem of a pair's runner CSV and checkpoint: ``<instance>.<agent>.<settings>``."""
    return f"{instance.name}.{agent_name}.{key}"


def run_pair(instance: Instance, agent_name: str, seeds: Sequence[int], n_steps: int, log_period: int,
             run_dir: Path, key: str, progress: bool) -> dict[str, Any]:
    """Run (or continue from its checkpoint) one agent on one instance over ``seeds``; returns its row."""
    agent = agents.get(agent_name)
    grid = runner.product([instance.build()], [agent.default_hparams], seeds)
    stem = run_stem(instance, agent_name, key)
    result = runner.run(agent, grid, n_steps, log_period=log_period, csv_path=run_dir / f"{stem}.csv",
                        checkpoint_path=run_dir / f"{stem}.npz", progress=progress)
    if result.steps.size == 0 or int(result.steps[-1]) != n_steps:
        raise RuntimeError(f"{instance.name} / {agent_name}: the run did not reach its last step")
    scores = result.column("normalized_cumulative_regret")[-1] / n_steps
    baseline = result.column("random_normalized_cumulative_regret")[-1] / n_steps
    order = np.argsort(np.asarray(grid.seeds))
    return dict(
        instance=instance.name, setting="episodic" if instance.episodic else "continuous", agent=agent_name,
        n_seeds=len(seeds), n_steps=n_steps, regret_per_step_mean=float(np.mean(scores)),
        regret_per_step_std=float(np.std(scores, ddof=1)) if len(seeds) > 1 else float("nan"),
        per_seed=" ".join(f"{float(x):.6g}" for x in scores[order]), random_baseline=float(baseline[0]),
        compile_s=float(result.compile_s), run_s=float(result.run_s),
        agent_steps_per_s=float(result.agent_steps_per_second), settings=key,
    )


def _scores(row: dict[str, str]) -> np.ndarray:
    return np.array([float(x) for x in row["per_seed"].split()])


def verdict(row: dict[str, str], random_row: dict[str, str] | None) -> str:
    """``"yes, every seed"`` (the agent's worst seed below the random agent's best), ``"yes"`` (mean below), ``"no"``
    or ``""`` (no random row, or the random agent itself)."""
    if random_row is None or row["agent"].startswith("random"):
        return ""
    mine, theirs = _scores(row), _scores(random_row)
    if mine.max() < theirs.min():
        return "yes, every seed"
    return "yes" if mine.mean() < theirs.mean() else "**no**"


def markdown(rows: Sequence[dict[str, str]], instances: Sequence[Instance], command: str, machine: str) -> str:
    """The table: one line per (instance, agent) of ``rows``, instances in ``instances``' order, agents in registry
    order with the random agent last."""
    by_pair = {(r["instance"], r["agent"]): r for r in rows}
    n_steps = {int(r["n_steps"]) for r in rows}
    n_seeds = {int(r["n_seeds"]) for r in rows}
    lines = [
        "# Normalised cumulative regret of the deep agents beside the random agent",
        "",
        f"Made by `{command}` ({', '.join(f'{n:,}' for n in sorted(n_steps))} steps, "
        f"{', '.join(map(str, sorted(n_seeds)))} seeds, the noiseless `{EMISSION}` emission, default (bsuite) "
        f"hyperparameters) on {machine}.",
        "",
        "Score: final `normalized_cumulative_regret` / steps (the paper's Table 2 number), mean ± std over seeds "
        "(ddof 1); 0 = optimal, 1 = worst policy. *Below random*: mean below the random agent's (*every seed*: the "
        "agent's worst seed below the random agent's best). *Uniform policy*: its exact per-step regret (the random "
        "agent's expectation). Steps/s: agent-steps (all seeds) per second of the lockstep loop, compilation "
        "excluded (wall-clock rates: they depend on the machine and its load).",
        "",
        "| instance | agent | regret / step | per seed | below random | agent-steps/s | compile s |",
        "|---|---|---|---|---|---|---|",
    ]
    for inst in instances:
        names = agents_of(inst.episodic)
        found = [by_pair[inst.name, n] for n in names if (inst.name, n) in by_pair]
        if not found:
            continue
        random_row = by_pair.get((inst.name, names[-1]))
        for r in found:
            lines.append(
                f"| {inst.name} | {r['agent']} | {float(r['regret_per_step_mean']):.3f} ± "
                f"{float(r['regret_per_step_std']):.3f} | {' '.join(f'{x:.3f}' for x in _scores(r))} | "
                f"{verdict(r, random_row)} | {float(r['agent_steps_per_s']):,.0f} | {float(r['compile_s']):.0f} |")
        lines.append(f"| {inst.name} | *uniform policy (exact)* | {float(found[0]['random_baseline']):.3f} | | | | |")
    missing = [f"{i.name} / {n}" for i in instances for n in agents_of(i.episodic) if (i.name, n) not in by_pair]
    if missing:
        lines += ["", f"Not run yet: {', '.join(missing)}."]
    return "\n".join(lines) + "\n"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--steps", type=int, default=50_000, help="steps per run (default %(default)s)")
    p.add_argument("--seeds", type=int, default=4, help="number of seeds, 0..N-1 (default %(default)s)")
    p.add_argument("--instances", nargs="+", default=list(DEFAULT_INSTANCES),
                   help="Family-size-setting items (default: %(default)s)")
    p.add_argument("--agents", nargs="+", default=None,
                   help="only these agents (default: every deep agent of each instance's setting and the random agent)")
    p.add_argument("--log-period", type=int, default=100, help="steps between indicator logs (%(default)s)")
    p.add_argument("--out", type=Path, default=Path("results/deep_agents_regret"), help="default %(default)s")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return p


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Run every missing (instance, agent) pair (module docstring) and write the table; returns ``{"rows": the
    table's rows, "ran": the pairs run by this call}``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return run_table(build_parser().parse_args(argv), ["jaxmdp-regret-table", "--deep", *argv])


def run_table(args: argparse.Namespace, command: Sequence[str]) -> dict[str, Any]:
    """:func:`main` on parsed arguments; ``command``: the command line the table names as its maker."""
    for name in ("steps", "seeds", "log_period"):
        if getattr(args, name) < 1:
            raise SystemExit(f"deep_agents_regret: --{name.replace('_', '-')} must be a positive integer")
    try:
        instances = [parse_instance(x) for x in args.instances]
        for name in args.agents or ():
            agents.get(name)
    except ValueError as err:
        raise SystemExit(f"deep_agents_regret: {err}") from None
    out = args.out
    (out / "runs").mkdir(parents=True, exist_ok=True)
    key = settings_key(args.steps, args.seeds, args.log_period)
    pairs = [(i, n) for i in instances for n in agents_of(i.episodic) if args.agents is None or n in args.agents]
    pairs = sorted(pairs, key=lambda p: p[1].startswith("boot_dqn"))  # stable: BootDQN last
    machine = (f"{platform.machine()}, {os.cpu_count()} cores, {jax.local_device_count()} JAX "
               f"{jax.default_backend()} device(s)")
    command = " ".join(shlex.quote(a) for a in command)
    ran = []

    def table() -> list[dict[str, str]]:
        rows = [r for r in read_rows(out / "rows.csv") if r["settings"] == key]
        (out / "deep_agents_regret.md").write_text(markdown(rows, instances, command, machine))
        return rows

    done = {(r["instance"], r["agent"]) for r in table()}
    for k, (inst, name) in enumerate(pairs):
        if (inst.name, name) in done:
            continue
        if not args.quiet:
            print(f"[{k + 1}/{len(pairs)}] {inst.name} / {name}", file=sys.stderr, flush=True)
        row = run_pair(inst, name, range(args.seeds), args.steps, args.log_period, out / "runs", key,
                       progress=not args.quiet)
        _append_row(out / "rows.csv", row)
        (out / "runs" / f"{run_stem(inst, name, key)}.npz").unlink(missing_ok=True)  # the row is the result now
        ran.append((inst.name, name))
        if not args.quiet:
            print(f"    {row['regret_per_step_mean']:.3f} regret/step, {row['agent_steps_per_s']:,.0f} agent-steps/s, "
                  f"compile {row['compile_s']:.0f} s, run {row['run_s']:.0f} s", file=sys.stderr, flush=True)
        table()
    return {"rows": table(), "ran": ran}
