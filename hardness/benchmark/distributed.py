"""The batches of a benchmark run as Ray tasks (``jaxmdp-benchmark run --ray [ADDRESS]``; optional extra
``[distributed]``).

The batches of a run (:mod:`hardness.benchmark.run`) are independent, so each can run in its own process on any
machine: with ``ray`` given, :func:`hardness.benchmark.run.run_benchmark` hands them to Ray, a local instance
(``True``) or a cluster (its address, ``"auto"`` for the one this machine belongs to), instead of running them one after
another. Without it this module, and Ray, are never imported.

Tasks. One task runs one batch with the same function as the local loop (``run._run_batch``: the runner, its
per-record CSV and its checkpoint) and returns the batch's files (``runs/<batch>.json``, ``.curves.npz``, ``.csv``)
to the driver, which alone writes them, ``members.csv``, ``batches.csv`` and the report; no shared file system is
needed. A worker that sees the run's folder (the driver leaves a token file in ``runs/`` for it to find) keeps the
checkpoint and the files there, as a local run does, so a restarted driver resumes a batch where it stopped; another
keeps them in a folder of its own machine (``<tmp>/jaxmdp-ray/<batch key>``), where a retry on that machine finds
the checkpoint. The driver claims the batches it hands out (:mod:`hardness.benchmark.claims`), so Ray drivers and
local processes may share a folder, and finished batches already in the folder are reused.

Resources (:class:`RayOptions`). Each task declares ``num_cpus`` (``cpus_per_batch``, default 1: XLA runs a lockstep
loop on one core, and the worker asks XLA for that many host devices, over which the runner shards the members),
``num_gpus`` (``gpus_per_batch``, default 1 where the cluster has a GPU, else 0) and ``memory``: the bytes the runner
may use. On a CPU a batch may use by default its share of its machine's memory (the machine's Ray ``memory`` times
``num_cpus`` over its cores), and the runner checks its compiled programs against it before running
(:mod:`jaxmdp.experiment.memory`); a batch that needs more is handed out again declaring the runner's own estimate
(``ProgramTooLarge.needed``) when some machine has that much, and is split otherwise (``run.split_batch``), as in a
local run. ``memory_limit`` of the run's config, when given, is declared for every batch instead. A fraction of a
GPU packs several batches on one GPU (a lockstep step of a small batch is bound by latency, not arithmetic;
docs/guide/scaling.md): each worker's JAX allocator is then limited to that fraction of 0.75 of the GPU's memory
(``XLA_PYTHON_CLIENT_MEM_FRACTION``, unless set), JAX's default share for one process, so that the runner's check
sees the worker's own share.

Faults. A worker that dies (killed, out of memory, its machine lost) has its task retried by Ray (``max_retries``),
which continues from the batch's last checkpoint where the retry sees it. An error raised by a batch (bad input, a
program that does not fit even alone or split) is not retried: the run stops with ``ValueError`` (for a
``ValueError``), :class:`~jaxmdp.experiment.memory.ProgramTooLarge`, or ``RuntimeError``, naming the batch and the
error; the tasks in flight are cancelled (their checkpoints stay) and the finished batches stay in the folder, so the
same command, once the cause is fixed, continues.

Progress: one bar of member-steps on the driver (:class:`jaxmdp.experiment.progress.Progress`), advanced as the
workers finish their chunks (when the bar is shown: a small actor collects the workers' counts) and their batches,
with the batches in flight on its line. ``batches.csv`` has each batch's compile and run seconds and the host and
pid of the worker that ran it; ``runs/<batch>.log`` adds a line per batch run on Ray (worker, step it resumed from).

Test seam (private): the environment variable ``JAXMDP_RAY_TEST_FAULT = "<batch id>:<chunks>:<marker path>"``, read
by the driver, makes the first attempt of that batch run ``<chunks>`` runner chunks (each checkpointed), write the
marker file and kill its own worker process (``SIGKILL``), as a machine lost mid-batch would.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import signal
import socket
import sys
import tempfile
import time
import traceback
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hardness.benchmark import claims, plans
from hardness.benchmark.plans import Batch
from jaxmdp.experiment.progress import Progress

__all__ = ["RayOptions", "MAX_RETRIES", "ray_options", "run_batches"]

#: Retries of a task whose worker died (Ray's ``max_retries``); errors raised by a batch are never retried.
MAX_RETRIES = 3
#: JAX's default share of a GPU's memory for one process; a batch on a fraction of a GPU gets that fraction of it.
GPU_MEMORY_SHARE = 0.75
#: The private test seam (module docstring).
FAULT_VARIABLE = "JAXMDP_RAY_TEST_FAULT"
_INSTALL = "Ray runs the batches with --ray: pip install 'jaxmdp-hardness[distributed]' (ray)"


@dataclasses.dataclass(frozen=True)
class RayOptions:
    """Where and how the batches run on Ray (module docstring).

    Attributes:
      address: a cluster's address (``"auto"``: the cluster this machine is part of, started with ``ray start``;
        ``"ray://host:10001"``: through Ray Client); ``None``: a local instance, started for the run (or the one
        already started in this process by ``ray.init``).
      cpus_per_batch: CPU cores a batch declares (and the host devices its runner shards the members over).
      gpus_per_batch: the GPUs a batch declares, a fraction packs several on one GPU; ``None``: 1 where the cluster
        has GPUs, else 0.
      max_retries: retries of a batch whose worker died.
    """

    address: str | None = None
    cpus_per_batch: float = 1
    gpus_per_batch: float | None = None
    max_retries: int = MAX_RETRIES


def ray_options(ray: bool | str | RayOptions) -> RayOptions:
    """``run_benchmark``'s ``ray`` as :class:`RayOptions`: ``True`` (a local instance), an address, or options;
    ``ValueError`` otherwise."""
    if ray is True:
        return RayOptions()
    if isinstance(ray, str) and ray.strip():
        return RayOptions(address=ray.strip())
    if not isinstance(ray, RayOptions):
        raise ValueError(f"ray must be True (a local Ray instance), a cluster address or RayOptions; got {ray!r}")
    for name in ("cpus_per_batch", "gpus_per_batch"):
        value = getattr(ray, name)
        if value is None and name == "gpus_per_batch":
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise ValueError(f"{name} must be a number >= 0; got {value!r}")
    if ray.cpus_per_batch == 0 and not ray.gpus_per_batch:
        raise ValueError("a batch must declare some CPU or GPU: cpus_per_batch and gpus_per_batch are both 0")
    if ray.gpus_per_batch is not None and ray.gpus_per_batch > 1 and ray.gpus_per_batch != int(ray.gpus_per_batch):
        raise ValueError(f"gpus_per_batch above 1 must be a whole number (Ray's rule); got {ray.gpus_per_batch!r}")
    if isinstance(ray.max_retries, bool) or not isinstance(ray.max_retries, int) or ray.max_retries < 0:
        raise ValueError(f"max_retries must be an integer >= 0; got {ray.max_retries!r}")
    return ray


def _import_ray() -> Any:
    try:
        import ray
    except ImportError as err:
        raise ImportError(_INSTALL) from err
    return ray


# ---------------------------------------------------------------------------------------------------------------
# The worker's side
# ---------------------------------------------------------------------------------------------------------------

_PREPARED = False  # whether this worker process has set up JAX (once, before its backend starts)


def _prepare_worker(cpus: float, gpus: float, cache: tuple[str, float] | None) -> None:
    """Set this worker's XLA host devices (one per CPU declared), its GPU memory share and the driver's persistent
    compilation cache, before JAX starts its backend (every task of a run asks the same)."""
    global _PREPARED
    if _PREPARED:
        return
    from jaxmdp.experiment.devices import DEVICE_COUNT_FLAG

    flags = [f for f in os.environ.get("XLA_FLAGS", "").split() if not f.startswith(DEVICE_COUNT_FLAG)]
    os.environ["XLA_FLAGS"] = " ".join(flags + [f"{DEVICE_COUNT_FLAG}={max(1, int(cpus))}"])
    if 0 < gpus < 1:
        os.environ.setdefault("XLA_PYTHON_CLIENT_MEM_FRACTION", f"{GPU_MEMORY_SHARE * gpus:.4f}")
    if cache is not None:
        import jax

        with contextlib.suppress(Exception):  # a folder this machine cannot write: compile without the cache
            Path(cache[0]).mkdir(parents=True, exist_ok=True)
            jax.config.update("jax_compilation_cache_dir", cache[0])
            jax.config.update("jax_persistent_cache_min_compile_time_secs", cache[1])
    _PREPARED = True


class _WorkerProgress(Progress):
    """What a worker's runner advances: it counts the batch's member-steps (``resumed``: those its checkpoint already
    held) and sends the counts to the driver's collector, if any."""

    def __init__(self, collector: Any, batch_id: str):
        super().__init__(0, quiet=True)
        self.collector, self.batch_id = collector, batch_id
        self.done = self.resumed = 0

    def _send(self) -> None:
        if self.collector is not None:
            self.collector.report.remote(self.batch_id, self.done, self.resumed)

    def update(self, n: int) -> None:
        self.done += int(n)
        self._send()

    def skip(self, n: int) -> None:
        self.resumed += int(n)
        self.done += int(n)
        self._send()


def _batch_task(batch: Batch, config: Any, out: str, token: str, resources: dict, memory_limit: int | None,
                cache: tuple[str, float] | None, collector: Any, fault: tuple[int, str] | None,
                own_agents: dict) -> dict:
    """One batch on a Ray worker (module docstring); returns ``status`` ``"finished"`` (with the worker, the step it
    resumed from and, when the worker does not see the run's folder, the batch's files), ``"too_large"`` (the
    runner's memory refusal) or ``"error"`` (a batch's error, with its traceback): errors travel as data, so that
    exceptions that do not pickle reach the driver too."""
    _prepare_worker(resources["num_cpus"], resources["num_gpus"], cache)
    import agents as agent_registry
    from hardness.benchmark import run
    from jaxmdp import runner

    for agent in own_agents.values():  # agents registered in the driver (agents.register), not shipped
        agent_registry.register(agent, replace=True)
    shared = (Path(out) / "runs" / token).exists()
    work = Path(out) / "runs" if shared else Path(tempfile.gettempdir()) / "jaxmdp-ray" / batch.key
    work.mkdir(parents=True, exist_ok=True)
    if memory_limit is not None:
        config = dataclasses.replace(config, memory_limit=int(memory_limit))
    bar = _WorkerProgress(collector, batch.id)
    try:
        if fault is not None and not Path(fault[1]).exists():
            run._run_batch(batch, config, work, fault[0], bar)
            Path(fault[1]).write_text(f"{os.getpid()}\n")
            os.kill(os.getpid(), signal.SIGKILL)
        complete = run._run_batch(batch, config, work, None, bar)
    except runner.ProgramTooLarge as err:
        return dict(status="too_large", message=str(err), needed=int(err.needed), available=int(err.available))
    except Exception as err:  # noqa: BLE001 (every error of a batch goes back to the driver)
        return dict(status="error", type=type(err).__name__, value_error=isinstance(err, ValueError),
                    message=str(err), traceback=traceback.format_exc())
    if not complete:
        return dict(status="error", type="RuntimeError", value_error=False, message="the batch stopped unfinished",
                    traceback="")
    files = None
    if not shared:
        files = {}
        for suffix in (".csv", ".curves.npz", ".json"):
            path = work / f"{batch.id}{suffix}"
            files[suffix] = path.read_bytes()
            path.unlink()
    return dict(status="finished", host=socket.gethostname(), pid=os.getpid(), files=files,
                resumed_at=bar.resumed // max(1, len(batch.members)))


class _Collector:
    """The driver's collector of the workers' member-step counts (a Ray actor, made only when the bar is shown)."""

    def __init__(self) -> None:
        self.counts: dict[str, tuple[int, int]] = {}

    def report(self, batch_id: str, done: int, resumed: int) -> None:
        self.counts[batch_id] = (done, resumed)

    def take(self) -> dict[str, tuple[int, int]]:
        counts, self.counts = self.counts, {}
        return counts


# ---------------------------------------------------------------------------------------------------------------
# The driver's side
# ---------------------------------------------------------------------------------------------------------------


def _fault(batch: Batch) -> tuple[int, str] | None:
    spec = os.environ.get(FAULT_VARIABLE, "")
    batch_id, _, rest = spec.partition(":")
    chunks, _, marker = rest.partition(":")
    return (int(chunks), marker) if spec and batch_id == batch.id else None


def _own_agents(ray: Any, config: Any, settings: dict) -> dict:
    """The run's agents that the driver registered (not shipped), for the workers to register; the modules that
    define them travel by value, since a worker may not be able to import them (a file given by its path)."""
    import agents as agent_registry

    names = {a for s in settings["sets"] for a in settings["agents"][s]} - set(agent_registry.SHIPPED)
    own = {n: agent_registry.get(n) for n in sorted(names)}
    _pickle_modules_by_value(ray, own.values())
    return own


def _pickle_modules_by_value(ray: Any, own_agents: Any) -> None:
    """Send the modules that define ``own_agents``' functions to the workers by value (not by import path)."""
    for agent in own_agents:
        for f in dataclasses.fields(agent):
            module = sys.modules.get(getattr(getattr(agent, f.name), "__module__", None) or "")
            if module is not None and module.__name__.split(".")[0] not in ("agents", "jaxmdp", "hardness", "jax"):
                with contextlib.suppress(Exception):
                    ray.cloudpickle.register_pickle_by_value(module)


def _cache() -> tuple[str, float] | None:
    import jax

    folder = jax.config.jax_compilation_cache_dir
    return None if not folder else (str(folder), float(jax.config.jax_persistent_cache_min_compile_time_secs))


def _write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


class _Driver:
    """The driver's loop over the batches of a call (:func:`run_batches`)."""

    def __init__(self, ray: Any, options: RayOptions, config: Any, view: plans.CallView, shard: Any, bar: Progress,
                 held: claims.Claims, poll_s: float):
        self.ray, self.options, self.config, self.view, self.shard = ray, options, config, view, shard
        self.bar, self.held, self.poll_s = bar, held, poll_s
        self.out = view.out
        self.run_dir = self.out / "runs"
        resources = ray.cluster_resources()
        gpus = options.gpus_per_batch
        if gpus is None:
            gpus = 1.0 if resources.get("GPU", 0) > 0 else 0.0
        self.resources = dict(num_cpus=float(options.cpus_per_batch), num_gpus=float(gpus))
        nodes = [n["Resources"] for n in ray.nodes() if n.get("Alive") and n["Resources"].get("CPU", 0) > 0]
        self.node_memory = max((n.get("memory", 0) for n in nodes), default=0)
        self.share = None  # a batch's default memory: its share of the smallest machine's (on a CPU)
        if config.memory_limit is None and not gpus and nodes and self.resources["num_cpus"] > 0:
            self.share = int(min(n.get("memory", 0) * self.resources["num_cpus"] / n["CPU"] for n in nodes))
        self.memory: dict[str, int] = {}  # batches handed out again with the runner's own estimate
        self.cache = _cache()
        self.own_agents: dict = {}
        self.token = f".ray-{uuid.uuid4().hex}"
        self.task = ray.remote(_batch_task)
        self.collector = ray.remote(num_cpus=0)(_Collector).remote() if bar.enabled else None
        self.pending: dict[Any, Batch] = {}
        self.counted: dict[str, tuple[int, int]] = {}  # batch -> member-steps advanced, skipped on the bar

    def capacity(self) -> int:
        """Batches the cluster runs at once, plus one ready to start as one finishes."""
        resources = self.ray.cluster_resources()
        fits = [resources.get(r, 0) / need for r, need in (("CPU", self.resources["num_cpus"]),
                                                            ("GPU", self.resources["num_gpus"])) if need > 0]
        return max(1, int(min(fits) + 1e-9)) + 1

    def submit(self, batch: Batch) -> None:
        memory = self.memory.get(batch.id, self.config.memory_limit or self.share)
        options = dict(self.resources, max_retries=self.options.max_retries, retry_exceptions=False)
        if memory:
            options["memory"] = int(memory)
        ref = self.task.options(**options).remote(
            batch, self.config, str(self.out), self.token, self.resources, memory, self.cache, self.collector,
            _fault(batch), self.own_agents)
        self.pending[ref] = batch

    def advance(self, batch: Batch, done: int, resumed: int) -> None:
        """Move the bar to ``done`` member-steps of ``batch``, of which ``resumed`` came from its checkpoint."""
        was_done, was_resumed = self.counted.get(batch.id, (0, 0))
        if resumed > was_resumed:
            self.bar.skip(resumed - was_resumed)
        step = (done - resumed) - (was_done - was_resumed)
        if step > 0:
            self.bar.update(step)
        self.counted[batch.id] = (max(done, was_done), max(resumed, was_resumed))

    def postfix(self) -> None:
        ids = [b.id for b in self.pending.values()]
        self.bar.set_postfix(f"{len(ids)} in flight: {', '.join(ids[:3])}{', ...' if len(ids) > 3 else ''}")

    def collect(self) -> None:
        if self.collector is None:
            return
        by_id = {b.id: b for b in self.pending.values()}
        for batch_id, (done, resumed) in self.ray.get(self.collector.take.remote()).items():
            if batch_id in by_id:
                self.advance(by_id[batch_id], done, resumed)

    def stop(self) -> None:
        """Cancel the tasks in flight (their checkpoints stay) and drop their claims."""
        for ref, batch in list(self.pending.items()):
            with contextlib.suppress(Exception):
                self.ray.cancel(ref, force=True)
            self.held.drop(batch.id, "stopped: the Ray run stopped")
        self.pending.clear()

    def finish(self, batch: Batch, result: dict) -> None:
        if result["files"] is not None:  # the worker did not see the folder: its files come with the result
            for suffix in (".csv", ".curves.npz", ".json"):  # the .json last: it marks the batch finished
                _write_bytes(self.run_dir / f"{batch.id}{suffix}", result["files"][suffix])
        with (self.run_dir / f"{batch.id}.log").open("a") as f:
            f.write(f"{claims._now()} ran-on-ray host={result['host']} pid={result['pid']} "
                    f"resumed_at_step={result['resumed_at']}\n")
        self.held.drop(batch.id, "finished")
        total = len(batch.members) * self.config.n_steps
        self.advance(batch, total, self.counted.get(batch.id, (0, 0))[1])

    def too_large(self, batch: Batch, result: dict, settings: dict) -> None:
        """A batch the runner refused for memory: hand it out again with its need, or split it, or stop."""
        from hardness.benchmark import run

        needed = result["needed"]
        if self.config.memory_limit is None and self.share is not None and self.memory.get(batch.id, 0) < needed \
                <= self.node_memory:
            self.memory[batch.id] = needed
            self.held.drop(batch.id, "retry: declaring the memory the runner needs")
            return
        self.held.drop(batch.id, "split: does not fit in memory")
        if self.config.max_members is not None or len(batch.members) < 2:
            from jaxmdp import runner

            raise runner.ProgramTooLarge(f"batch {batch.id}: {result['message']}", needed, result["available"])
        halves = run.split_batch(batch, settings)
        self.bar.write(f"{batch.id} does not fit in memory ({result['message']}); split into {len(halves)} parts",
                       log=True)
        plans.replace(self.out, dataclasses.asdict(batch), [dataclasses.asdict(h) for h in halves])

    def loop(self, settings: dict, done: set, ran: list, others: list) -> None:
        from hardness.benchmark.tables import _finished

        while True:
            mine = self.view.share(self.shard)
            flying = {b.id for b in self.pending.values()}
            for b in mine:  # batches that other processes finished
                if b.id not in done and b.id not in flying and _finished(self.run_dir, b) is not None:
                    done.add(b.id)
                    others.append(b.id)
                    self.bar.update(len(b.members) * self.config.n_steps)
            todo = [b for b in mine if b.id not in done and b.id not in flying]
            if not todo and not self.pending:
                return
            capacity = self.capacity()
            for b in todo:
                if len(self.pending) >= capacity:
                    break
                if not self.held.take(b.id):
                    continue
                if _finished(self.run_dir, b) is not None:  # finished between the look and the claim
                    self.held.drop(b.id)
                    continue
                self.submit(b)
            if not self.pending:  # every batch left is another process's
                self.bar.set_postfix(f"waiting for {len(todo)} batches of other processes")
                time.sleep(self.poll_s)
                continue
            self.postfix()
            ready, _ = self.ray.wait(list(self.pending), num_returns=1,
                                     timeout=None if self.collector is None else 1.0)
            self.collect()
            for ref in ready:
                batch = self.pending.pop(ref)
                try:
                    result = self.ray.get(ref)
                except Exception as err:  # the task itself failed (its worker died more than max_retries times)
                    self.held.drop(batch.id, f"failed: {type(err).__name__}")
                    raise RuntimeError(f"batch {batch.id} failed on Ray: {err}") from err
                if result["status"] == "too_large":
                    self.too_large(batch, result, settings)
                    continue
                if result["status"] == "error":
                    self.held.drop(batch.id, f"failed: {result['type']}")
                    message = f"batch {batch.id} failed: {result['type']}: {result['message']}"
                    if result["value_error"]:
                        raise ValueError(message)
                    raise RuntimeError(f"{message}\n{result['traceback']}")
                self.finish(batch, result)
                ran.append(batch.id)
                done.add(batch.id)
                plans.write_folder_tables(self.out)


@contextlib.contextmanager
def _connected(ray: Any, options: RayOptions) -> Iterator[None]:
    """Ray, connected: the instance this process already has, else one started (or joined) for the run and shut
    down after it."""
    if ray.is_initialized():
        yield
        return
    ray.init(address=options.address, include_dashboard=False)
    try:
        yield
    finally:
        ray.shutdown()


def run_batches(
    config: Any,
    settings: dict,
    view: plans.CallView,
    shard: tuple[int, int] | None,
    bar: Progress,
    held: claims.Claims,
    done: set,
    ran: list,
    others: list,
    ray: bool | str | RayOptions,
    *,
    poll_s: float = 2.0,
    stop_at: tuple[int, int] | None = None,
) -> bool:
    """Run the call's unfinished batches (of ``shard``) as Ray tasks (module docstring), adding their ids to ``done``
    and ``ran`` (and to ``others`` those other processes finished); ``bar`` counts member-steps and ``held`` holds the
    driver's claims. Returns whether every batch of the call finished (always, unless it raises)."""
    if stop_at is not None:
        raise ValueError("stop_at interrupts the local loop; it cannot be combined with ray")
    options = ray_options(ray)
    module = _import_ray()
    with _connected(module, options):
        driver = _Driver(module, options, config, view, shard, bar, held, poll_s)
        driver.own_agents = _own_agents(module, config, settings)
        (driver.run_dir / driver.token).write_text("the run's folder, as Ray workers see it\n")
        try:
            driver.loop(settings, done, ran, others)
        finally:
            driver.stop()
            (driver.run_dir / driver.token).unlink(missing_ok=True)
    return True
