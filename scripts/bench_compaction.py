"""Stream compaction (``jaxmdp.sampling.compaction``) against its version at a git revision, in one process.

Two measurements, each a ``vmap`` over ``--members`` members, best of ``--repeats`` alternating calls:

1. ``compact_with_count`` alone on flags that are true with probability ``--rejected`` (the Gamma sampler's first
   round rejects 1-5% of its entries), ``size = n // 16 + 64`` as the sampler's first buffer; ms per call.
2. The Gamma sampler (``sample_log_gamma``) on Dirichlet posterior concentrations ``1/S + counts``, counts ~
   Poisson(0.3), ``[S, A, S]`` with ``A = 4``: the baseline's compaction swapped into the sampler while it is traced;
   ns per Gamma entry.

Both versions must give the same bits (checked). Compile seconds of one ``jit(...).lower(...).compile()`` are shown
beside each. Numbers: docs/benchmarks/bench_compaction.md.

    PYTHONPATH=$PWD python scripts/bench_compaction.py --baseline 336932d
"""

from __future__ import annotations

import argparse
import contextlib
import time

import jax
import jax.numpy as jnp
import numpy as np

from baseline_module import load_revision  # scripts/ is on the path of a script run as python scripts/NAME.py
from bench_doc import interleaved_best
from jaxmdp.sampling import beta_sampling, compaction


@contextlib.contextmanager
def sampler_compaction(fn):
    """``beta_sampling`` calling ``fn`` as its ``compact_with_count`` while a function is traced."""
    saved = beta_sampling.compact_with_count
    beta_sampling.compact_with_count = fn
    try:
        yield
    finally:
        beta_sampling.compact_with_count = saved


def compiled(fn, args, compact_fn):
    """``jit(fn)`` compiled for ``args`` with ``compact_fn`` in the sampler, and the compile seconds."""
    with sampler_compaction(compact_fn):
        t = time.perf_counter()
        exe = jax.jit(fn).lower(*args).compile()
        return exe, time.perf_counter() - t


def same_bits(exes: dict, args) -> None:
    """Every executable gives the first one's bits on ``args``."""
    outs = [jax.tree.leaves(e(*args)) for e in exes.values()]
    for name, out in zip(list(exes)[1:], outs[1:]):
        assert all(np.array_equal(a, b) for a, b in zip(outs[0], out)), name


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--baseline", default="main", help="git revision timed against (%(default)s)")
    p.add_argument("--members", type=int, default=3)
    p.add_argument("--repeats", type=int, default=20)
    p.add_argument("--rejected", type=float, default=0.05, help="fraction of true flags (%(default)s)")
    p.add_argument("--flags", type=int, nargs="+", default=[20_000, 640_000, 3_600_000])
    p.add_argument("--states", type=int, nargs="+", default=[100, 400, 948])
    args = p.parse_args()
    base = load_revision(args.baseline, "jaxmdp/sampling/compaction.py", "baseline_compaction")
    versions = {args.baseline: base.compact_with_count, "current": compaction.compact_with_count}
    B = args.members

    print(f"compact_with_count, {B} members, {args.rejected:.0%} true, size n // 16 + 64: ms per call (compile s)")
    print(f"| n | {' | '.join(versions)} | speed-up |\n|---|---|---|---|")
    for n in args.flags:
        flags = jax.random.bernoulli(jax.random.key(1), args.rejected, (B, n))
        exes, secs = {}, {}
        for name, fn in versions.items():
            exes[name], secs[name] = compiled(jax.vmap(lambda f, fn=fn: fn(f, n // 16 + 64)), (flags,), fn)
        same_bits(exes, (flags,))
        best = interleaved_best(exes, (flags,), args.repeats)
        cells = [f"{best[k] * 1e3:.3f} ({secs[k]:.2f})" for k in versions]
        print(f"| {n:,} | {' | '.join(cells)} | {best[args.baseline] / best['current']:.2f}x |")

    print(f"\nsample_log_gamma on {B} members' [S, 4, S] posteriors: ns per entry (compile s)")
    print(f"| S | entries | {' | '.join(versions)} | speed-up |\n|---|---|---|---|---|")
    for S in args.states:
        keys = jax.random.split(jax.random.key(0), B)
        alpha = (1.0 / S + jax.random.poisson(jax.random.key(2), 0.3, (B, S, 4, S))).astype(jnp.float32)
        exes, secs = {}, {}
        for name, fn in versions.items():  # a function of its own per version: jit caches traces by function
            sampler = jax.vmap(lambda k, a: beta_sampling.sample_log_gamma.__wrapped__(k, a))
            exes[name], secs[name] = compiled(sampler, (keys, alpha), fn)
        same_bits(exes, (keys, alpha))
        best = interleaved_best(exes, (keys, alpha), args.repeats)
        cells = [f"{best[k] / alpha.size * 1e9:.2f} ({secs[k]:.1f})" for k in versions]
        print(f"| {S} | {alpha.size:,} | {' | '.join(cells)} | {best[args.baseline] / best['current']:.2f}x |")


if __name__ == "__main__":
    main()
