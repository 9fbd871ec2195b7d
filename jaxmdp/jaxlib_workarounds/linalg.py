"""Dense linear solves that cannot deadlock jaxlib 0.10.2's CPU backend under ``vmap``.

``jnp.linalg.solve`` on a batch of matrices lowers to one LAPACK custom call (``getrf`` + triangular solves) over the
whole batch. On CPU, jaxlib 0.10.2 splits such a batch into chunks scheduled on XLA's intra-op thread pool and
blocks the calling thread until they are done (``jax::ParallelBatchMap``). When the calling thread is itself a pool
worker, which happens whenever XLA runs independent operations of a program concurrently, or several devices'
programs at once (the runner's ``shards``), every worker can end up waiting for chunks that no free worker will ever
run: the process hangs with all threads asleep. Observed in jaxmdp: UCRL2 on DeepSea 10 (20 seeds, 2 host devices)
hung for good after step 5 000 inside the batched policy evaluation of its policy estimate; a program with eight
independent ``vmap``-ed solves of 10 matrices 55 x 55 hangs on every run with a pool of two threads, with one
device or two. (The parallel path is reportedly compiled out of later jaxlib releases.)

:func:`solve` is ``jnp.linalg.solve`` for one system; under ``vmap`` it solves the systems one after another
(``lax.map``), so every LAPACK call sees a batch of one and never waits on the pool. Each system is solved by the
same LAPACK routines, so the results are bitwise those of the batched call. It is also faster for the batches jaxmdp
uses (on the project's 2-core CPU: 64 x 25 x 25 in 0.6 ms instead of 1.0 ms, 80 x 55 x 55 1.1 vs 1.3 ms, 4 x 400 x
400 0.29 vs 0.68 s) except for very many tiny systems (1 024 x 5 x 5: 2.3 ms instead of 0.55 ms).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["solve"]


@jax.custom_batching.custom_vmap
def solve(a: jax.Array, b: jax.Array) -> jax.Array:
    """``x`` with ``a x = b`` for one square ``a[S, S]`` and ``b[S]`` (or ``b[S, K]``), by LU with partial pivoting
    (``jnp.linalg.solve``); batched systems are solved one at a time (module docstring). Not differentiable."""
    return jnp.linalg.solve(a, b)


@solve.def_vmap
def _solve_one_at_a_time(axis_size: int, in_batched: list[bool], a: jax.Array, b: jax.Array):
    a_batched, b_batched = in_batched
    if not a_batched:
        a = jnp.broadcast_to(a, (axis_size, *a.shape))
    if not b_batched:
        b = jnp.broadcast_to(b, (axis_size, *b.shape))
    # ``solve`` inside the map is unbatched at this level; an enclosing vmap applies this rule again.
    return jax.lax.map(lambda ab: solve(*ab), (a, b)), True
