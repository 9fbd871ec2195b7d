"""Normalised cumulative regret of every tabular agent beside the random agent's, on small RiverSwim and DeepSea
(see :mod:`hardness.analysis.regret_table`; ``--help`` lists the options)."""

from jaxmdp.experiment.compilation import enable_compilation_cache
from jaxmdp.experiment.devices import use_every_core

if __name__ == "__main__":
    use_every_core()  # one lockstep loop per core: the runner shards the members over the host devices
    enable_compilation_cache()  # the persistent compilation cache (JAXMDP_COMPILATION_CACHE=0: off)

    from hardness.analysis.regret_table import main

    main()
