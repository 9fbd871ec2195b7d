"""Analyses built on the hardness measures and the agents (paper §3.2, App. D; §4 and Table 1-2):

* :mod:`~hardness.analysis.scenarios`: the four hardness scenarios, measures over a sweep of MDPs;
* :mod:`~hardness.analysis.near_optimal`: the regret of a tuned near-optimal agent (random search over PSRL/UCRL2);
* :mod:`~hardness.analysis.plotting`: the scenario figures (mean over seeds with a bootstrap band);
* :mod:`~hardness.analysis.sweep_cli`: the sweep command line, ``jaxmdp-sweep`` (CSV/JSON/PNG, resumable);
* :mod:`~hardness.analysis.regret_table`: every tabular agent against the random agent on small instances;
* :mod:`~hardness.analysis.measure_evaluation`: rank correlations of the measures with the near-optimal agent's
  regret (paper §2.3's completeness);
* :mod:`~hardness.analysis.completeness`: rank correlations with a two-stage bootstrap (seeds within MDPs, MDPs) and
  the leave-one-MDP-out pair of measures; :mod:`~hardness.analysis.completeness_benchmark`: that test on benchmark
  run folders;
* :mod:`~hardness.analysis.statements`: the paper's scenario statements checked under both variants.

This sub-package and :mod:`hardness.benchmark` are the only places that import :mod:`agents`; :mod:`hardness`
itself (the measures) imports :mod:`jaxmdp` only, and does not import this sub-package.
"""
