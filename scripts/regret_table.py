"""Normalised cumulative regret of every tabular agent beside the random agent's, on small RiverSwim and DeepSea
(see :mod:`hardness.analysis.regret_table`; ``--help`` lists the options)."""

from jaxmdp.experiment.devices import use_every_core

if __name__ == "__main__":
    use_every_core()  # one lockstep loop per core: the runner shards the members over the host devices

    from hardness.analysis.regret_table import main

    main()
