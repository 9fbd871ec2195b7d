"""The Gamma sampler's trial deviates from a fused Threefry hash against two ``jax.random.uniform`` arrays.

Every Marsaglia-Tsang trial of :mod:`jaxmdp.sampling.beta_sampling` needs two uniforms per entry. This script times,
in one process, one after the other (each the best of ``--repeats`` calls after a compiling one), on a batch of
Dirichlet concentrations shaped like episodic PSRL's posterior (``[B, S, A, S]``, prior 0.32, one entry in a hundred
with counts):

* two ``jax.random.uniform`` arrays: the random words of a round as the sampler drew them before the fused hash;
* :func:`jaxmdp.sampling.beta_sampling.trial_deviates`: one written-out Threefry hash per entry, ``erf_inv`` included;
* :func:`agents.posteriors.dirichlet_sample`: the whole draw that the agents make;
* ``H`` backups of the drawn model (:func:`jaxmdp.dynamic_programming.finite_horizon_value_iteration`, as episodic
  PSRL plans): the rest of a plan, for scale;
* with ``--baseline PATH`` (another version of ``jaxmdp/sampling/beta_sampling.py``, e.g. main's), the whole draw
  with this tree's sampler and with the baseline's, each timed inside one compiled program as the runner pays it
  (``profile_continuous_plans.in_program_seconds``), alternating, best of ``--repeats`` rounds.

Usage: ``python scripts/bench_fused_draws.py [--batch 8] [--states 400] [--actions 3] [--horizon 40] [--repeats 5]
[--baseline PATH] [--doc PATH]`` (``--doc`` appends a dated section); numbers are nanoseconds per entry of the
``[B, S, A, S]`` array, wall time over all cores.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp

from agents.posteriors import dirichlet_sample
from baseline_module import load_file
from bench_doc import append_section, best_seconds
from jaxmdp import dynamic_programming as dp
from jaxmdp.sampling.beta_sampling import sample_log_gamma, trial_deviates
from profile_continuous_plans import in_program_seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--states", type=int, default=400)
    parser.add_argument("--actions", type=int, default=3)
    parser.add_argument("--horizon", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--baseline", help="another beta_sampling.py, timed against this tree's in one program")
    parser.add_argument("--doc", help="append the table to this Markdown file")
    args = parser.parse_args()
    B, S, A, H = args.batch, args.states, args.actions, args.horizon
    shape = (B, S, A, S)
    n = B * S * A * S
    counts = (jax.random.uniform(jax.random.key(1), shape) < 0.01) * 5.0
    alpha = 0.32 + counts
    keys = jax.random.split(jax.random.key(0), B)
    rewards = jax.random.uniform(jax.random.key(2), (B, S, A))

    def two_uniforms(key, a):
        k_x, k_w = jax.random.split(key)
        return jax.random.uniform(k_x, (a.size,)), jax.random.uniform(k_w, (a.size,))

    jax_random = jax.jit(jax.vmap(two_uniforms))
    fused = jax.jit(jax.vmap(lambda key, a: trial_deviates(key, a.size, jnp.float32)))
    dirichlet = jax.jit(jax.vmap(dirichlet_sample))
    vi = jax.jit(jax.vmap(lambda p, r: dp.finite_horizon_value_iteration(p, rewards=r, H=H)))
    model = dirichlet(keys, alpha)
    rows = [
        ("two jax.random.uniform arrays", best_seconds(lambda: jax_random(keys, alpha), args.repeats)),
        ("trial_deviates (fused Threefry)", best_seconds(lambda: fused(keys, alpha), args.repeats)),
        ("dirichlet_sample (whole draw)", best_seconds(lambda: dirichlet(keys, alpha), args.repeats)),
        (f"{H} backups of the drawn model", best_seconds(lambda: vi(model, rewards), args.repeats)),
    ]
    if args.baseline:
        baseline = load_file(args.baseline, "baseline_beta").sample_log_gamma
        draws = {name: lambda k, a, f=f: jax.vmap(lambda kk, aa: dirichlet_sample(kk, aa, f))(k, a)
                 for name, f in (("this tree", sample_log_gamma), ("baseline", baseline))}
        best = dict.fromkeys(draws, float("inf"))
        for _ in range(args.repeats):  # alternating; each draw's program is compiled once
            for name, draw in draws.items():
                best[name] = min(best[name], in_program_seconds(draw, keys, alpha, repeats=1))
        rows += [(f"dirichlet_sample in one program, {name}", t) for name, t in best.items()]
    lines = [f"`[B, S, A, S] = {list(shape)}`, best of {args.repeats}", "", "| what | ms | ns per entry |",
             "|---|---|---|"]
    lines += [f"| {name} | {t * 1e3:.1f} | {t / n * 1e9:.2f} |" for name, t in rows]
    print("\n".join(lines))
    if args.doc:
        append_section(args.doc, "The Gamma sampler's deviates from a fused Threefry hash", None, lines)


if __name__ == "__main__":
    main()
