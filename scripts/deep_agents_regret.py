"""Normalised cumulative regret of the deep agents beside the random agent's on small ``state_info`` BlockMDPs
(see :mod:`hardness.analysis.deep_regret`; ``--help`` lists the options)."""

from jaxmdp.experiment.devices import use_every_core

if __name__ == "__main__":
    use_every_core()  # one lockstep loop per core: the runner shards the seeds over the host devices

    from hardness.analysis.deep_regret import main

    main()
