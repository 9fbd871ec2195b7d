"""The regret of a tuned near-optimal agent: the optimistic measure of hardness of the paper's analysis (§3.2, App. D).

For every MDP of a grid, the near-optimal agent of the setting (PSRL episodic, UCRL2 continuous; App. D) is tuned
by random search over its hyperparameter space (:mod:`agents.search_spaces`) and the best candidate is then run
once more with fresh seeds; its expected cumulative regret is the measure. Both phases are one lockstep runner call
each (:mod:`jaxmdp.experiment.runner`): the search is ``MDPs x candidates x tuning seeds`` members, the evaluation one
member per ``(MDP, evaluation seed)``.

The objective of the search is the mean over tuning seeds of the per-step normalised cumulative regret after
``n_steps`` (App. E, ``normalized_cumulative_regret``), so candidates are compared on the regret they incur, not on
rewards they were lucky to draw. Candidate 0 is the agent's default (the benchmark's tuned values). Evaluating the
winner on seeds it was not selected with avoids the optimistic bias of reporting the best search score.

Budget: the paper searches 120 candidates, 3 seeds and 200 000 steps per MDP (with a two-minute wall-clock cap per
run, which we do not have: every run completes its steps). The defaults here are much smaller so that a sweep
finishes in minutes on a laptop; pass the paper's numbers for the paper's protocol.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import jax
import numpy as np

import agents as agent_registry
from agents.search_spaces import sample_candidates
from jaxmdp._checks import check_int
from jaxmdp.experiment import runner
from jaxmdp.mdp import MDP

__all__ = ["NEAR_OPTIMAL_AGENTS", "TUNING_SEED_OFFSET", "NearOptimalRegret", "near_optimal_agent", "tuned_regret"]

#: The near-optimal agent of each setting (App. D).
NEAR_OPTIMAL_AGENTS = {"episodic": "psrl_episodic", "continuous": "ucrl2"}

#: Tuning runs use seeds ``TUNING_SEED_OFFSET + j``, disjoint from any evaluation seed below it.
TUNING_SEED_OFFSET = 1_000_000


@dataclasses.dataclass(frozen=True)
class NearOptimalRegret:
    """Tuned near-optimal regret of ``M`` MDPs.

    Attributes:
      agent: the agent's name.
      n_steps: steps of every run.
      cumulative_regret: ``[M]`` expected cumulative regret of the evaluation run (App. A.1).
      normalized_cumulative_regret: ``[M]`` its per-step normalised version (App. E), in ``[0, n_steps]``.
      best_hparams: the selected hyperparameters, stacked ``[M]``.
      search_scores: ``[M, n_candidates]`` mean normalised cumulative regret of every candidate over the tuning
        seeds (empty second axis when there was no search).
      run_s, compile_s: seconds spent running and compiling both phases.
    """

    agent: str
    n_steps: int
    cumulative_regret: np.ndarray
    normalized_cumulative_regret: np.ndarray
    best_hparams: Any
    search_scores: np.ndarray
    run_s: float
    compile_s: float


def near_optimal_agent(episodic: bool):
    """The near-optimal agent of the setting: PSRL (episodic) or UCRL2 (continuous), paper App. D."""
    return agent_registry.get(NEAR_OPTIMAL_AGENTS["episodic" if episodic else "continuous"])


def tuned_regret(
    mdps: MDP,
    eval_seeds: Sequence[int],
    *,
    n_steps: int = 10_000,
    n_candidates: int = 8,
    n_tuning_seeds: int = 1,
    search_seed: int = 0,
    progress: bool = False,
) -> NearOptimalRegret:
    """Tune the near-optimal agent on every MDP of ``mdps`` and measure its regret (module docstring).

    Args:
      mdps: a stacked batch of ``M`` MDPs of one setting (:func:`jaxmdp.stack`, or a ``vmap`` of a kernel transform).
      eval_seeds: ``M`` seeds, one per MDP, of the evaluation runs (below :data:`TUNING_SEED_OFFSET`).
      n_steps: interaction steps of every run (search and evaluation).
      n_candidates: random-search budget per MDP; ``1`` runs the default hyperparameters without a search.
      n_tuning_seeds: seeds per candidate in the search.
      search_seed: key of the candidate draw (:func:`agents.search_spaces.sample_candidates`).
      progress: print the runner's progress to stderr.

    Raises:
      ValueError: naming the argument, for non-positive budgets, a seed count that does not match ``mdps`` or
        seeds that collide with the tuning seeds.
    """
    if not isinstance(mdps, MDP) or mdps.T.ndim != 4:
        raise ValueError("mdps must be a stacked batch of MDPs (jaxmdp.stack or a vmapped transform)")
    M = mdps.T.shape[0]
    n_steps = check_int("n_steps", n_steps, 1)
    n_candidates = check_int("n_candidates", n_candidates, 1)
    n_tuning_seeds = check_int("n_tuning_seeds", n_tuning_seeds, 1)
    eval_seeds = [check_int("eval_seeds", s, 0) for s in eval_seeds]
    if len(eval_seeds) != M:
        raise ValueError(f"eval_seeds must hold one seed per MDP ({M}); got {len(eval_seeds)}")
    if max(eval_seeds) >= TUNING_SEED_OFFSET:
        raise ValueError(f"eval_seeds must be below {TUNING_SEED_OFFSET} (the tuning seeds start there)")
    agent = near_optimal_agent(mdps.episodic)

    # Candidate 0 is the default set, so one candidate is the defaults without a search.
    cands = sample_candidates(agent, jax.random.key(search_seed), n_candidates)
    run_s = compile_s = 0.0
    if n_candidates > 1:
        # Member (m, c, j) of the search: MDP m, candidate c, tuning seed j (MDP-major, as runner.product orders).
        m, c, j = np.unravel_index(np.arange(M * n_candidates * n_tuning_seeds), (M, n_candidates, n_tuning_seeds))
        tuning_seeds = TUNING_SEED_OFFSET + j
        g = runner.grid(mdps, jax.tree.map(lambda x: x[c], cands), runner.seed_keys(tuning_seeds), mdp_index=m,
                        hparams_index=c, seeds=tuning_seeds)
        search = runner.run(agent, g, n_steps, progress=progress)
        scores = search.column("normalized_cumulative_regret")[-1].reshape(M, n_candidates, n_tuning_seeds)
        scores = scores.mean(axis=-1)
        best = np.argmin(scores, axis=1)
        run_s += search.run_s
        compile_s += search.compile_s
    else:
        scores = np.zeros((M, 0))
        best = np.zeros(M, np.int64)
    best_hparams = jax.tree.map(lambda x: x[best], cands)

    g = runner.grid(mdps, best_hparams, runner.seed_keys(eval_seeds), mdp_index=np.arange(M), seeds=eval_seeds)
    final = runner.run(agent, g, n_steps, progress=progress)
    return NearOptimalRegret(
        agent=agent.name,
        n_steps=n_steps,
        cumulative_regret=final.column("cumulative_regret")[-1],
        normalized_cumulative_regret=final.column("normalized_cumulative_regret")[-1],
        best_hparams=best_hparams,
        search_scores=scores,
        run_s=run_s + final.run_s,
        compile_s=compile_s + final.compile_s,
    )
