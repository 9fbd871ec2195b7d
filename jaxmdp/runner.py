"""``jaxmdp.runner``: a short name for :mod:`jaxmdp.experiment.runner` (``from jaxmdp import runner``;
``runner.product(...)``, ``runner.run(...)``). Everything is defined there."""

from jaxmdp.experiment.runner import (  # noqa: F401
    DEFAULT_CHUNKS,
    MEMBER_COLUMNS,
    Grid,
    ProgramTooLarge,
    RunResult,
    default_chunk_steps,
    grid,
    plan_slots_for,
    product,
    record_steps,
    run,
    seed_keys,
    stack_hparams,
    take_members,
)
from jaxmdp.experiment.runner import __all__  # noqa: F401
