"""Normalised cumulative regret of the deep agents beside the random agent's on small ``state_info`` BlockMDPs
(see :mod:`hardness.analysis.deep_regret`; ``--help`` lists the options)."""

from jaxmdp.experiment.compilation import enable_compilation_cache
from jaxmdp.experiment.devices import use_every_core

if __name__ == "__main__":
    use_every_core()  # one lockstep loop per core: the runner shards the seeds over the host devices
    enable_compilation_cache()  # the persistent compilation cache (JAXMDP_COMPILATION_CACHE=0: off)

    from hardness.analysis.deep_regret import main

    main()
