"""The experiment layer: agents run in lockstep on grids of MDPs, with exact regret indicators (paper §3.3, App. A.1).

* :mod:`~jaxmdp.experiment.agent_interface`: what an agent is (pure functions on pytrees) and what it may know;
* :mod:`~jaxmdp.experiment.members`: the members of a run, (MDP, hyperparameters, key) triples (``product``, ``grid``);
* :mod:`~jaxmdp.experiment.runner`: the host driver of a run (``run``: validation, compilation, chunks, CSV,
  checkpoints);
* :mod:`~jaxmdp.experiment.lockstep`: the lockstep loop's step, plan, log and record as pure functions, and
  :mod:`~jaxmdp.experiment.programs`: the compiled programs made of them;
* :mod:`~jaxmdp.experiment.planning`: planning only the members that asked, in rounds;
* :mod:`~jaxmdp.experiment.indicators`: the exact expected regret of a policy and the reference's CSV columns;
* :mod:`~jaxmdp.experiment.records` and :mod:`~jaxmdp.experiment.checkpoints`: what a run writes;
* :mod:`~jaxmdp.experiment.compilation`: the scripts' persistent compilation cache and compile-time counters
  (``enable_compilation_cache``, called by entry points only);
* :mod:`~jaxmdp.experiment.progress`: the one progress display of long runs (member-steps per second, time left,
  each compilation with its seconds), on a terminal only.

It imports the MDP model of :mod:`jaxmdp` and nothing else of this project; agents import it.
"""

from jaxmdp.experiment.compilation import enable_compilation_cache

__all__ = ["enable_compilation_cache"]
