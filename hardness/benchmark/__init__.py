"""The Colosseum benchmark end to end (paper §3.3, App. F, App. G): the 80 MDPs of its four settings as data
(:mod:`.suite`), named MDP sets (:mod:`.sets`, of :class:`.instance.Instance`), the hyperparameter-search MDP
samplers (:mod:`.samplers`), the random search (:mod:`.search`), the resumable benchmark run (:mod:`.run`, with its
emission maps in :mod:`.emissions` and its result tables in :mod:`.tables`), its report (:mod:`.report`, with the
aggregates of :mod:`.aggregate` and other runs' results beside its own from :mod:`.baselines`, the shipped agents'
committed results among them) and the
paper's published numbers (:mod:`.published`, read from the package data in ``data/``). The command line is
``jaxmdp-benchmark`` (:mod:`hardness.cli.benchmark`).

Not imported by :mod:`hardness`; like :mod:`hardness.analysis` it sits above the measures and may import
:mod:`agents`. Submodules are imported on use (``from hardness.benchmark import run``).
"""
