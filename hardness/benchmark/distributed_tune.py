"""The tuner's searches as Ray tasks (``jaxmdp-benchmark tune --ray [ADDRESS]``; optional extra ``[distributed]``).

The random search of one agent (:func:`hardness.benchmark.search.search`: every candidate on the agent's search set,
one lockstep grid per size bucket, each bucket's result needed to pick the next) is sequential within itself, but
the agents' searches are independent. With ``--ray`` each agent's search is one Ray task, with the resources of
:class:`hardness.benchmark.distributed.RayOptions` (``num_cpus``, a fraction of a GPU); the driver writes each
winner into the tuned file as its task finishes, so an interrupted call keeps every finished agent and the same
command continues with the others.

Faults: a worker that dies has its task retried (``max_retries``); the search's runner checkpoints its buckets in
the agent's work folder, which a retry continues from where it sees that folder (the same machine, or a shared file
system; elsewhere it searches in a folder of its own machine, ``<tmp>/jaxmdp-ray-tune/<agent>/<budget>``). An error
of a search (bad input, a program that does not fit) stops the call with ``ValueError`` or ``RuntimeError`` naming
the agent; the winners already written stay.
"""

from __future__ import annotations

import tempfile
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from hardness.benchmark import distributed
from hardness.benchmark.distributed import RayOptions

__all__ = ["tune_agents"]


def _search_task(name: str, budget: Any, n_buckets: int, work_dir: str, note: str, resources: dict,
                 cache: tuple[str, float] | None, own_agents: dict) -> dict:
    """One agent's search on a Ray worker; returns ``status`` ``"finished"`` with the tuned-file entry, or
    ``"error"`` (errors travel as data, as for the benchmark's batches)."""
    distributed._prepare_worker(resources["num_cpus"], resources["num_gpus"], cache)
    import agents as agent_registry
    from hardness.benchmark import search

    for agent in own_agents.values():
        agent_registry.register(agent, replace=True)
    work = Path(work_dir)
    if not work.exists():  # the driver's folder (made before submitting) is not visible here: one of this machine
        work = Path(tempfile.gettempdir()) / "jaxmdp-ray-tune" / name / work.name
    try:
        entry = search.tuned_entry(name, budget, n_buckets=n_buckets, work_dir=work, note=note)
    except Exception as err:  # noqa: BLE001 (every error of a search goes back to the driver)
        return dict(status="error", type=type(err).__name__, value_error=isinstance(err, ValueError),
                    message=str(err), traceback=traceback.format_exc())
    return dict(status="finished", entry=entry)


def tune_agents(
    names: Sequence[str],
    budget: Any,
    work_dirs: dict[str, Path],
    ray: bool | str | RayOptions,
    *,
    n_buckets: int = 4,
    note: str = "",
    on_entry: Callable[[str, dict], None],
) -> dict[str, dict]:
    """Search every agent of ``names`` with ``budget`` as one Ray task each (module docstring); ``on_entry(name,
    entry)`` is called on the driver as each finishes (the tuner writes the entry there). Returns ``{name: entry}``.
    """
    options = distributed.ray_options(ray)
    module = distributed._import_ray()
    with distributed._connected(module, options):
        gpus = options.gpus_per_batch
        if gpus is None:
            gpus = 1 if module.cluster_resources().get("GPU", 0) > 0 else 0
        resources = dict(num_cpus=options.cpus_per_batch, num_gpus=gpus)
        import agents as agent_registry

        own = {n: agent_registry.get(n) for n in names if n not in agent_registry.SHIPPED}
        distributed._pickle_modules_by_value(module, own.values())
        task = module.remote(max_retries=options.max_retries, **resources)(_search_task)
        cache = distributed._cache()
        for name in names:
            Path(work_dirs[name]).mkdir(parents=True, exist_ok=True)
        pending = {task.remote(n, budget, n_buckets, str(work_dirs[n]), note, resources, cache, own): n
                   for n in names}
        entries: dict[str, dict] = {}
        try:
            while pending:
                ready, _ = module.wait(list(pending), num_returns=1)
                name = pending.pop(ready[0])
                result = module.get(ready[0])
                if result["status"] == "error":
                    kind = ValueError if result["value_error"] else RuntimeError
                    raise kind(f"tuning {name} failed: {result['type']}: {result['message']}\n{result['traceback']}")
                entries[name] = result["entry"]
                on_entry(name, result["entry"])
        finally:
            for ref in pending:
                module.cancel(ref, force=True)
    return entries
