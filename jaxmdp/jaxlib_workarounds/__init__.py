"""Workarounds for defects of jaxlib's CPU backend (0.10.2 and later), kept in one place so that they can be deleted
together once jaxlib is fixed: the YNNPACK miscompilation guard, applied to the affected releases only
(:mod:`jaxmdp.jaxlib_workarounds.xla_cpu`), and a linear
solve, and a wrapper for any function of matrices (a QR, say), that cannot deadlock the thread pool under ``vmap``
(:mod:`jaxmdp.jaxlib_workarounds.linalg`)."""
