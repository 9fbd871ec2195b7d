"""Exact random samplers that ``jax.random`` lacks or makes slow under ``vmap``: Gamma, log-Gamma and Beta draws
(:mod:`jaxmdp.sampling.beta_sampling`) and the stable compaction they rely on (:mod:`jaxmdp.sampling.compaction`)."""

from jaxmdp.sampling.beta_sampling import sample_beta, sample_log_gamma

__all__ = ["sample_beta", "sample_log_gamma"]
