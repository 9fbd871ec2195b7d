"""Benchmark: the step's Beta reward draw with 1, 2 or 3 rounds before its loop (``unrolled_rounds`` of
:func:`jaxmdp.sampling.beta_shared.sample_beta_shared`), as the step draws it: one draw per member and step, ``vmap``
over ``--members``, ``--steps`` steps in one jitted ``lax.scan`` (a fresh key per step and member), in one process,
interleaved, best of ``--repeats``.

The values are the same for every choice (tests/test_beta_rewards.py); the question is the cost. On a CPU an extra
round is more arithmetic for every member; on a GPU the loop's trips are what cost (kernel launches and a predicate
read back), so rounds before the loop may pay (docs/benchmarks/gpu_h100.md: Beta rewards cost 3-4x a step there).
Two shape mixes: ``worst`` (every member at ``a = b = 1``, where a round of four trials fails most often, 4.4e-4) and
``mixed`` (shapes uniform on (0.5, 5)).

    python scripts/bench_beta_rounds.py                        # 1 024 and 16 384 members
    python scripts/bench_beta_rounds.py --members 1024 16384 262144

Writes a section to ``docs/benchmarks/bench_beta_rounds.md`` (with the command) unless ``--doc ''``.
"""

from __future__ import annotations

import argparse
import functools
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from bench_doc import append_section  # scripts/ is on the path of a script run as python scripts/NAME.py
from jaxmdp.sampling.beta_shared import sample_beta_shared

ROOT = Path(__file__).resolve().parent.parent
ROUNDS = (1, 2, 3)


@functools.partial(jax.jit, static_argnames=("n_steps", "unrolled"))
def _draws(key: jax.Array, a: jax.Array, b: jax.Array, n_steps: int, unrolled: int) -> jax.Array:
    """``n_steps`` steps of one Beta draw per member; returns the sum of the draws (so nothing is optimised away)."""
    keys = jax.random.split(key, a.shape[0])
    draw = jax.vmap(functools.partial(sample_beta_shared, unrolled_rounds=unrolled))

    def step(total, t):
        return total + draw(jax.vmap(lambda k: jax.random.fold_in(k, t))(keys), a, b), None

    return jax.lax.scan(step, jnp.zeros(a.shape, a.dtype), jnp.arange(n_steps))[0].sum()


def _shapes(mix: str, n: int) -> tuple[jax.Array, jax.Array]:
    if mix == "worst":
        return jnp.ones((n,)), jnp.ones((n,))
    k_a, k_b = jax.random.split(jax.random.key(1))
    uniform = functools.partial(jax.random.uniform, shape=(n,), minval=0.5, maxval=5.0)
    return uniform(k_a), uniform(k_b)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--members", type=int, nargs="+", default=[1024, 16384], help="members drawn in lockstep")
    p.add_argument("--steps", type=int, default=500, help="steps (draws per member) per timed run")
    p.add_argument("--repeats", type=int, default=5, help="timed runs per setting (best is reported)")
    p.add_argument("--doc", default=str(ROOT / "docs/benchmarks/bench_beta_rounds.md"), help="'' to skip")
    args = p.parse_args(argv)
    rows = []
    for n in args.members:
        for mix in ("worst", "mixed"):
            a, b = _shapes(mix, n)
            programs, compile_s, best = {}, {}, {k: np.inf for k in ROUNDS}
            for k in ROUNDS:
                t = time.perf_counter()
                programs[k] = _draws.lower(jax.random.key(0), a, b, args.steps, k).compile()
                programs[k](jax.random.key(0), a, b).block_until_ready()
                compile_s[k] = time.perf_counter() - t
            for rep in range(args.repeats):
                for k in ROUNDS:  # interleaved
                    t = time.perf_counter()
                    programs[k](jax.random.key(rep + 1), a, b).block_until_ready()
                    best[k] = min(best[k], time.perf_counter() - t)
            rates = {k: n * args.steps / best[k] / 1e6 for k in ROUNDS}
            rows.append(f"| {n:,} | {mix} | " + " | ".join(f"{rates[k]:.1f}" for k in ROUNDS)
                        + " | " + " | ".join(f"{rates[k] / rates[1]:.2f}x" for k in ROUNDS[1:])
                        + " | " + (" / ".join(f"{compile_s[k]:.1f}" for k in ROUNDS) if mix == "worst"
                                   else "(the programs above)") + " |")
            print(rows[-1], flush=True)
    if args.doc:
        append_section(args.doc, "The step's Beta draw: rounds before the loop (`unrolled_rounds`)", argv, [
            f"{args.steps} steps, best of {args.repeats} interleaved runs.",
            "",
            "| members | shapes | M draws/s, 1 round before the loop | 2 rounds | 3 rounds | 2 / 1 | 3 / 1 "
            "| compile s |",
            "|---|---|---|---|---|---|---|---|",
            *rows,
        ])

if __name__ == "__main__":
    main()
