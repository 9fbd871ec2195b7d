"""The console commands of the package (``[project.scripts]`` in ``pyproject.toml``), each a ``main(argv=None) -> int``:

* ``jaxmdp-sweep`` (:mod:`~hardness.cli.sweep`): a hardness scenario (``--scenario 1..4``, paper §3.2, App. D);
  ``jaxmdp-sweep-prand`` is its scenario 1;
* ``jaxmdp-regret-table`` (:mod:`~hardness.cli.regret_table`): every tabular agent's regret beside the random agent's;
  ``--deep``: the deep agents on BlockMDPs;
* ``jaxmdp-benchmark`` (:mod:`~hardness.cli.benchmark`): the Colosseum benchmark, ``run``, ``report`` and ``tune``
  (paper §3.3, App. F, App. G);
* ``jaxmdp-measure-evaluation`` (:mod:`~hardness.cli.measure_evaluation`): rank correlations of the measures with a
  near-optimal agent's regret (paper §2.3);
* ``jaxmdp-completeness`` (:mod:`~hardness.cli.completeness`): rank correlations of every measure, and of the diameter
  with the value norm, with the tuned agents' regret across each benchmark setting's 20 MDPs (paper §2.3);
* ``jaxmdp-scenario-statements`` (:mod:`~hardness.cli.scenario_statements`): the paper's §3.2 / App. D statements
  about the measures in scenarios 1-4, checked under both variants.

Every command takes ``--out``, ``--quiet`` and ``--no-compile-cache``; a command that runs seeds takes ``--seeds N``
for seeds ``0..N-1``; every command ends with one line on stderr giving its wall time and the part spent compiling
(:mod:`jaxmdp.experiment.compilation`). Process-wide JAX settings (the persistent compilation cache, one host device
per core) are made here, in the commands, never when a library module is imported.
"""
