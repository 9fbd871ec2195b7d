"""The Colosseum benchmark end to end (paper §3.3, App. F, App. G): the 80 MDPs of its four settings as data
(:mod:`.suite`), named MDP sets (:mod:`.sets`), the hyperparameter-search MDP samplers (:mod:`.samplers`), the
random search (:mod:`.search`), the resumable benchmark run (:mod:`.run`), its report (:mod:`.report`) and the
paper's published numbers (:mod:`.published`).

Not imported by :mod:`hardness`; like :mod:`hardness.analysis` it sits above the measures and may import
:mod:`agents`. Submodules are imported on use (``from hardness.benchmark import run``).
"""
