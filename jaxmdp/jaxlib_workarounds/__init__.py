"""Workarounds for defects of jaxlib's CPU backend, kept in one place so that they can be deleted together: the
YNNPACK miscompilation guard, applied to the affected jaxlib versions only
(:mod:`jaxmdp.jaxlib_workarounds.xla_cpu`), and a linear solve, and a wrapper for any function of matrices (a QR,
say), that cannot deadlock the thread pool under ``vmap`` (:mod:`jaxmdp.jaxlib_workarounds.linalg`). The defects and
the evidence: docs/performance.md, jaxlib workarounds."""
