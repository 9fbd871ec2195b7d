"""Deep agents on BlockMDPs (paper §3.1, App. A.2 and App. G): flax networks trained with optax, one pure
interface per agent (:class:`jaxmdp.experiment.agent_interface.Agent` with ``observation="emission"``), vmapped over
seeds and hyperparameter sets by the lockstep runner."""
