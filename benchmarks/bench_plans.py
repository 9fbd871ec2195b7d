"""The epoch and episode plans of the model-based agents at the benchmark's largest buckets, in one process,
interleaved, best of ``--reps`` (other processes share the machine: read the ratios).

1. **PSRL continuous against the dense extended MDP.** On the largest MDP of the continuous settings (MiniGridRooms
   ``prms_1`` of "continuous ergodic", 948 states x 3 actions, ``psi = 60`` candidates per pair at the tuned
   hyperparameters), after ``--play`` uniformly random steps (``update`` only, then one plan for the values a run's
   previous plan leaves; several counts: early in a run, where every chosen row is a jump, and late, 1 000 000 steps,
   where every pair has observed mass and the evaluation is banded), one plan as the agent makes it
   (:func:`agents.psrl_continuous.plan`: the candidates on the successor slots,
   :mod:`agents.extended_policy_iteration`) against the dense construction of the same draws: the ``[max_psi, S, A,
   S]`` candidate kernels (:func:`agents.extended_policy_iteration.candidate_kernels`), the extended MDP ``[S, A
   max_psi, S]`` (:func:`~agents.extended_policy_iteration.extended_mdp`) and Howard's policy iteration with exact
   evaluation on it (:func:`jaxmdp.dynamic_programming.policy_iteration`, the same stopping rule), warm-started from
   the same values. Both plans are checked to agree within policy iteration's guarantee (values within ``eps / (1 -
   gamma)``, ``eps = 1e-5 (1 + max|V|)``: either may stop at a policy whose improvement is below ``eps``), and the
   share of states with the same real action is reported.
2. **UCRL2** on the same MDP and states: its plan (extended value iteration on the successor slots), its policy
   estimate (:func:`agents.ucrl2.warm_policy`, banded, warm-started as the runner does).
3. **Episodic PSRL** on the largest episodic MDP (MiniGridEmpty ``prms_0`` of "episodic ergodic", 400 states x 3
   actions, ``H = 23``): its plan, the exact posterior draw alone (:func:`agents.posteriors.dirichlet_sample` of the
   ``[S, A, S]`` concentrations: ns per Dirichlet entry), the backward induction alone and the policy estimate.

    python benchmarks/bench_plans.py [--reps 3] [--play 5000 100000 1000000] [--update-docs]
    python benchmarks/bench_plans.py --smoke
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

import agents
import jaxmdp
from agents import extended_policy_iteration as epi
from agents import psrl_continuous as pc
from agents import psrl_episodic as pe
from agents import ucrl2
from agents.posteriors import dirichlet_sample, normal_gamma_mean, normal_gamma_sample
from hardness.benchmark import sets
from jaxmdp import dynamic_programming as dp
from jaxmdp.experiment import compilation
from jaxmdp.experiment.agent_interface import spec_of
from jaxmdp.gth import band_order

import _common

NAME = "bench_plans"
CONTINUOUS = ("continuous ergodic", "MiniGridRooms/prms_1")
EPISODIC = ("episodic ergodic", "MiniGridEmpty/prms_0")
N_STEPS = 500_000


def build_mdp(set_name: str, label: str, smoke: bool) -> jaxmdp.MDP:
    """The benchmark's MDP (seed 0), or at ``smoke`` size a small one of the same kind."""
    if smoke:
        return jaxmdp.make("RiverSwim", episodic=sets.is_episodic(set_name), seed=0, size=6)
    return sets.instance(set_name, label).build(0)


def spec(mdp: jaxmdp.MDP):
    """The agent's spec as the runner hands it on a CPU: with the MDP's band order."""
    order = band_order(mdp)
    return spec_of(mdp, N_STEPS, jnp.asarray(order.order), order.bandwidth)


def played(agent, mdp, hp, n_steps: int, key):
    """The agent's state after ``n_steps`` uniformly random actions (``update`` only), with a plan due."""
    state = _common.random_play(agent, mdp, spec(mdp), hp, n_steps, key)
    return state.replace(plan_due=jnp.ones((), bool))


@jax.jit
def dense_psrl_plan(key: jax.Array, state: pc.PSRLContinuousState) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The dense construction of the plan that :func:`agents.psrl_continuous.plan` makes with ``key`` (discounted):
    the same draws as dense candidate kernels, the ``[S, A max_psi, S]`` extended MDP and policy iteration on it.
    Returns ``(Q[S, A], V[S], iterations)``."""
    k_r, k_p = jax.random.split(key)
    R = normal_gamma_sample(k_r, state.rewards)
    P = epi.candidate_kernels(k_p, state)
    T, R_ext, mask = epi.extended_mdp(R, P, state.action_mask)
    gamma = jnp.asarray(state.hparams.discount, T.dtype)
    start = dp.greedy(dp.q_values(T, state.u, gamma, R_ext), mask)
    res = dp.policy_iteration(T, gamma, rewards=R_ext, policy=start)
    S, A = state.Q.shape
    Q = jnp.max(jnp.where(mask, res.Q, -jnp.inf).reshape(S, A, -1), axis=-1)
    return Q, res.V, res.iterations


def psrl_continuous(mdp, plays: Sequence[int], reps: int) -> list[dict]:
    """Measurement 1 (module docstring), one row per random-play length."""
    agent = agents.get("psrl_continuous")
    S, A = int(np.sum(np.asarray(mdp.state_mask))), int(np.sum(np.asarray(mdp.action_mask)))
    hp = agent.default_hparams.replace(max_psi=pc.psi(agent.default_hparams, S, A))
    structured = jax.jit(agent.plan)
    rows = []
    for n in plays:
        state = played(agent, mdp, hp, n, jax.random.key(0))
        state = jax.block_until_ready(structured(jax.random.key(1), state)).replace(plan_due=jnp.ones((), bool))
        key = jax.random.key(2)
        best = _common.interleaved_best(
            {"structured": structured, "dense": dense_psrl_plan}, (key, state), reps)
        new = structured(key, state)
        Q, V, iterations = dense_psrl_plan(key, state)
        scale = 1.0 + float(jnp.max(jnp.abs(V)))
        err = float(jnp.max(jnp.abs(new.u - V))) / scale
        if err > 1e-5 / (1 - float(hp.discount)):
            raise SystemExit(f"the plans disagree after {n} steps: |V - V_dense| / (1 + max|V|) = {err:.1e}")
        same = float(np.mean(np.argmax(np.asarray(new.Q), -1) == np.argmax(np.asarray(Q), -1)))
        d = epi.draws(jax.random.split(key)[1], state)
        rows.append(dict(play=n, S=S, A=A, psi=int(state.constants.psi), structured_s=best["structured"],
                         dense_s=best["dense"], iterations=int(new.plan_iterations), dense_iterations=int(iterations),
                         value_error=err, same_actions=same, pairs_at_eta=int(jnp.sum(d.posterior)),
                         jump_rows=float(jnp.mean(jnp.all(d.p_minus == 0, axis=-1)))))
        r = rows[-1]
        print(f"PSRL continuous, {n} steps: structured {r['structured_s'] * 1e3:.1f} ms, dense {r['dense_s'] * 1e3:.1f}"
              f" ms ({r['dense_s'] / r['structured_s']:.1f}x); |V - V_dense| / (1 + max|V|) = {err:.1e}, "
              f"same real action at {same:.1%} of states", flush=True)
    return rows


def ucrl2_costs(mdp, plays: Sequence[int], reps: int) -> list[dict]:
    """Measurement 2 (module docstring)."""
    agent = agents.get("ucrl2")
    plan, estimate = jax.jit(agent.plan), jax.jit(ucrl2.warm_policy)
    rows = []
    for n in plays:
        state = played(agent, mdp, agent.default_hparams, n, jax.random.key(0))
        key = jax.random.key(1)
        start = estimate(state, None)[1]
        best = _common.interleaved_best(
            {"plan": lambda k, s: plan(k, s), "estimate": lambda k, s: estimate(s, start)}, (key, state), reps)
        rows.append(dict(play=n, plan_s=best["plan"], estimate_s=best["estimate"],
                         evi_iterations=int(plan(key, state).evi_iterations)))
        r = rows[-1]
        print(f"UCRL2, {n} steps: plan {r['plan_s'] * 1e3:.2f} ms ({r['evi_iterations']} sweeps), policy estimate "
              f"{r['estimate_s'] * 1e3:.2f} ms", flush=True)
    return rows


def psrl_episodic(mdp, plays: Sequence[int], reps: int) -> list[dict]:
    """Measurement 3 (module docstring)."""
    agent = agents.get("psrl_episodic")
    plan, policy = jax.jit(agent.plan), jax.jit(agent.policy)
    draw = jax.jit(lambda k, s: dirichlet_sample(k, pe._alpha(s)))

    @jax.jit
    def induction(P, s):
        R = normal_gamma_mean(s.rewards)
        return dp.finite_horizon_value_iteration(P, rewards=R, H=s.Q.shape[0], horizon=s.horizon)[0]

    rows = []
    for n in plays:
        state = played(agent, mdp, agent.default_hparams, n, jax.random.key(0))
        key = jax.random.key(1)
        P = draw(key, state)
        best = _common.interleaved_best(
            {"plan": plan, "draw": draw, "induction": lambda k, s: induction(P, s), "estimate": lambda k, s: policy(s)},
            (key, state), reps)
        S, A = state.Q.shape[1:]
        rows.append(dict(play=n, S=S, A=A, H=state.Q.shape[0], plan_s=best["plan"], draw_s=best["draw"],
                         induction_s=best["induction"], estimate_s=best["estimate"],
                         ns_per_entry=best["draw"] / (S * A * S) * 1e9))
        r = rows[-1]
        print(f"PSRL episodic, {n} steps: plan {r['plan_s'] * 1e3:.1f} ms = draw {r['draw_s'] * 1e3:.1f} ms "
              f"({r['ns_per_entry']:.1f} ns per entry) + induction {r['induction_s'] * 1e3:.1f} ms; policy estimate "
              f"{r['estimate_s'] * 1e3:.1f} ms", flush=True)
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=3, help="timed rounds of each measurement (best is kept)")
    ap.add_argument("--play", type=int, nargs="+", default=[5000, 100000, 1000000],
                    help="random steps before the plan (%(default)s)")
    ap.add_argument("--only", choices=["psrl_continuous", "ucrl2", "psrl_episodic"], nargs="+",
                    default=["psrl_continuous", "ucrl2", "psrl_episodic"], help="measurements to run")
    _common.add_common_args(ap)
    args = ap.parse_args(argv)
    if args.smoke:
        args.reps, args.play = 1, [200]
    cache_folder, compile_stats = compilation.setup_compilation(args.no_compile_cache)
    t_script = time.perf_counter()
    continuous = build_mdp(*CONTINUOUS, args.smoke)
    results = {}
    if "psrl_continuous" in args.only:
        results["psrl_continuous"] = psrl_continuous(continuous, args.play, args.reps)
    if "ucrl2" in args.only:
        results["ucrl2"] = ucrl2_costs(continuous, args.play, args.reps)
    if "psrl_episodic" in args.only:
        results["psrl_episodic"] = psrl_episodic(build_mdp(*EPISODIC, args.smoke), args.play, args.reps)
    _common.publish(NAME, "Plans at the largest buckets", body(results, args), args, argv)
    print(compilation.time_report(time.perf_counter() - t_script, compile_stats.snapshot(), cache_folder),
          file=sys.stderr)
    return 0


def body(results: dict, args) -> list[str]:
    """The table's lines."""
    where = "" if args.smoke else " at 948 states"
    lines = [f"One process, interleaved, best of {args.reps}; wall ms per call (each call its own program). States "
             "after uniformly random play of the given steps."]
    if "psrl_continuous" in results:
        lines += [
            "",
            f"PSRL continuous{where}: the plan against the dense extended MDP of the same draws "
            "(`[S, A psi, S]`, policy iteration); value difference in units of `1 + max|V|`.",
            "",
            "| random steps | psi | pairs at eta | jump rows | plan ms | dense ms | speed-up | PI steps (dense) "
            "| value diff | same action |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in results["psrl_continuous"]:
            lines.append(
                f"| {r['play']:,} | {r['psi']} | {r['pairs_at_eta']} | {r['jump_rows']:.0%} | "
                f"{r['structured_s'] * 1e3:.1f} | {r['dense_s'] * 1e3:.1f} | {r['dense_s'] / r['structured_s']:.1f}x | "
                f"{r['iterations']} ({r['dense_iterations']}) | {r['value_error']:.1e} | {r['same_actions']:.1%} |")
    if "ucrl2" in results:
        lines += ["", f"UCRL2{where}:", "", "| random steps | plan ms | EVI sweeps | policy estimate ms |",
                  "|---|---|---|---|"]
        for r in results["ucrl2"]:
            lines.append(f"| {r['play']:,} | {r['plan_s'] * 1e3:.2f} | {r['evi_iterations']} | "
                         f"{r['estimate_s'] * 1e3:.2f} |")
    if "psrl_episodic" in results:
        lines += ["", "PSRL episodic" + ("" if args.smoke else " at 400 states, H = 23") + ":", "",
                  "| random steps | plan ms | posterior draw ms | ns per Dirichlet entry | backward induction ms "
                  "| policy estimate ms |", "|---|---|---|---|---|---|"]
        for r in results["psrl_episodic"]:
            lines.append(f"| {r['play']:,} | {r['plan_s'] * 1e3:.1f} | {r['draw_s'] * 1e3:.1f} | "
                         f"{r['ns_per_entry']:.1f} | {r['induction_s'] * 1e3:.1f} | {r['estimate_s'] * 1e3:.1f} |")
    return lines


if __name__ == "__main__":
    sys.exit(main())
