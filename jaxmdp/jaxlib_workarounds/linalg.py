"""Dense linear algebra that cannot deadlock jaxlib 0.10.2's CPU backend under ``vmap``.

``jnp.linalg.solve`` and ``jnp.linalg.qr`` on a batch of matrices lower to LAPACK custom calls (``getrf`` and
triangular solves; ``geqrf`` and ``orgqr``) over the whole batch. On CPU, jaxlib 0.10.2 splits such a batch into
chunks scheduled on XLA's intra-op thread pool and blocks the calling thread until they are done
(``jax::ParallelBatchMap``). When the calling thread is itself a pool worker, which happens whenever XLA runs
independent operations of a program concurrently, or several devices' programs at once (the runner's ``shards``),
every worker can end up waiting for chunks that no free worker will ever run: the process hangs with all threads
asleep. Observed in jaxmdp:

* UCRL2 on DeepSea 10 (20 seeds, 2 host devices) hung for good after step 5 000 inside the batched policy evaluation
  of its policy estimate; a program with eight independent ``vmap``-ed solves of 10 matrices 55 x 55 hangs on every
  run with a pool of two threads, with one device or two;
* the recurrent actor-critic's learning probes (8 members initialised under ``vmap``) hung on their first run under
  pytest-xdist: both intra-op workers of the process sat in ``jax::QrFactorization<F32>::Kernel`` ->
  ``jax::ParallelBatchMap`` -> ``absl::BlockingCounter::Wait``, two of the LSTM's orthogonal recurrent-kernel
  initialisations (``jax.random.orthogonal``, a QR of a normal draw) waiting on each other's chunks.

(The parallel path is reportedly compiled out of later jaxlib versions.) ``ParallelBatchMap`` runs a batch of one
inline, on the calling thread, so :func:`one_at_a_time` gives a function a ``vmap`` rule that handles the batch one
set of arguments after another (``lax.map``): :func:`solve` is ``jnp.linalg.solve`` so wrapped, and the recurrent
actor-critic wraps its orthogonal initialiser (``agents.deep.networks.orthogonal``). Each matrix goes through the
same LAPACK routines as in the batched call, so the results are bitwise those of the batched call. For :func:`solve`
it is also faster for the batches jaxmdp uses (tens of matrices of tens to hundreds of rows), slower only for very
many tiny systems (thousands of 5 x 5 matrices).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

__all__ = ["solve", "one_at_a_time"]


def one_at_a_time(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn`` with a ``vmap`` rule that runs it on one set of arguments at a time: unbatched arguments are broadcast
    to the batch and the wrapped function itself runs under ``lax.map`` (so that an enclosing ``vmap`` applies the rule
    again). Every LAPACK call inside ``fn`` then sees one matrix and runs inline (module docstring); the numbers are
    those of ``vmap(fn)``. Every parameter of ``fn`` must be an array (JAX key arrays included): ``custom_vmap``
    passes defaults as arguments, so options such as ``mode="reduced"`` are fixed inside ``fn``."""
    wrapped = jax.custom_batching.custom_vmap(fn)

    def rule(axis_size: int, in_batched: list[bool], *args: Any):
        args = tuple(a if b else jnp.broadcast_to(a, (axis_size, *a.shape)) for a, b in zip(args, in_batched))
        out = jax.lax.map(lambda xs: wrapped(*xs), args)
        return out, jax.tree.map(lambda _: True, out)

    wrapped.def_vmap(rule)
    return wrapped


@one_at_a_time
def solve(a: jax.Array, b: jax.Array) -> jax.Array:
    """``x`` with ``a x = b`` for one square ``a[S, S]`` and ``b[S]`` (or ``b[S, K]``), by LU with partial pivoting
    (``jnp.linalg.solve``); batched systems are solved one at a time (module docstring). Not differentiable."""
    return jnp.linalg.solve(a, b)
