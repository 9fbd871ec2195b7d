"""The Colosseum benchmark end to end (paper §3.3, App. F, App. G): named MDP sets (:mod:`.sets`), the
hyperparameter-search MDP samplers (:mod:`.samplers`), the random search (:mod:`.search`), the resumable benchmark
run (:mod:`.run`), its report (:mod:`.report`) and the paper's published numbers (:mod:`.published`).

Submodules are imported on use (``from hardness.benchmark import run``): the run and the report pull in the agents and
matplotlib, which the measures do not need.
"""
