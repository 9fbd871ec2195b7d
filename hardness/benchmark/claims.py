"""One batch, one runner: claims on the batches of a benchmark folder shared by several processes.

A process that starts a batch claims it: ``runs/<batch>.claim``, next to the batch's checkpoint, holds the claimant's
host, pid, a token of the claim, when it started (the claimant's clock, for people to read) and a heartbeat count that
a thread of the claimant raises every ``heartbeat_s`` seconds while it holds the claim. The claim goes when the batch
stops (finished, interrupted or failed). Every claim, heartbeat, takeover and drop is made under the folder's lock
(:func:`folder_lock`: ``benchmark.lock``, a :class:`filelock.FileLock`, which the operating system drops when its
process dies; where the file system has no such locks filelock uses an exclusive-create lock file), so two processes
never claim one batch, and each is logged in ``runs/<batch>.log`` (the writer's time, host and pid).

Another process takes a claim over when its holder is gone:

* on the same machine (host name, kernel boot id and pid namespace all equal): its pid is not running (or is a zombie,
  or is the taker's own pid under another token, a previous process's);
* on any machine: its heartbeat count has not changed for ``stale_s`` seconds of the *taker's own monotonic clock*.

No time written by one machine is compared with another's clock (neither the claim's start time nor a file's
modification time, which a file server may stamp), so the rule holds on a shared file system whose hosts' clocks
disagree. It needs only that a file one host writes is seen by the others within ``stale_s - heartbeat_s`` (NFS
caches file attributes for up to a minute by default) and that a live holder's thread beats at least once per
``stale_s`` (a process stopped for longer, e.g. suspended, loses its claim and the batch runs twice: the same
results, written atomically). Containers on one machine count as one machine only when they share the pid namespace.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import os
import socket
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

from filelock import FileLock

__all__ = ["HEARTBEAT_S", "STALE_S", "folder_lock", "machine", "Claims"]

#: Seconds between a holder's heartbeats.
HEARTBEAT_S = 30.0
#: Seconds (of the observer's clock) without a heartbeat after which a claim of another machine is taken over.
STALE_S = 300.0


def folder_lock(out: str | os.PathLike) -> FileLock:
    """The lock of a benchmark folder (held for the short read-modify-writes of its plan, tables and claims)."""
    Path(out).mkdir(parents=True, exist_ok=True)
    return FileLock(str(Path(out) / "benchmark.lock"))


def _read(path: Path, default: str = "") -> str:
    try:
        return path.read_text().strip()
    except OSError:
        return default


def machine() -> str:
    """This process's machine: host name, kernel boot id and pid namespace (where the system tells them)."""
    boot = _read(Path("/proc/sys/kernel/random/boot_id"))
    try:
        pid_ns = os.readlink("/proc/self/ns/pid")
    except OSError:
        pid_ns = ""
    return f"{socket.gethostname()}/{boot}/{pid_ns}"


def _running(pid: int) -> bool:
    """Whether process ``pid`` of this machine runs (a zombie does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    stat = _read(Path(f"/proc/{pid}/stat"))
    return not stat or stat.rsplit(")", 1)[-1].split()[:1] not in (["Z"], ["X"])


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


@dataclasses.dataclass
class _Seen:
    """What an observer saw of another process's claim: its token and beat, since when (the observer's clock)."""

    token: Any
    beat: Any
    since: float


class Claims:
    """The claims of this process on the batches of folder ``out`` (module docstring); a context manager, inside
    which a thread beats for the claims held and on leaving which every claim still held is dropped."""

    def __init__(
        self,
        out: str | os.PathLike,
        *,
        heartbeat_s: float = HEARTBEAT_S,
        stale_s: float = STALE_S,
        clock: Callable[[], float] = time.monotonic,
    ):
        if not 0 < heartbeat_s < stale_s:
            raise ValueError(f"heartbeat_s must be positive and below stale_s; got {heartbeat_s} and {stale_s}")
        self.out = Path(out)
        self.run_dir = self.out / "runs"
        self.heartbeat_s, self.stale_s, self.clock = float(heartbeat_s), float(stale_s), clock
        self.host, self.machine, self.pid = socket.gethostname(), machine(), os.getpid()
        self.held: dict[str, dict] = {}  # batch id -> our claim
        self.lost: list[str] = []  # batches whose claim another process took over while this one held it
        self._seen: dict[str, _Seen] = {}
        self._lock = folder_lock(self.out)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> Claims:
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self._stop.clear()
        self._thread = threading.Thread(target=self._beat_loop, name="benchmark-claims", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        for batch_id in list(self.held):
            self.drop(batch_id, "dropped")

    def _path(self, batch_id: str) -> Path:
        return self.run_dir / f"{batch_id}.claim"

    def _log(self, batch_id: str, event: str) -> None:
        with (self.run_dir / f"{batch_id}.log").open("a") as f:
            f.write(f"{_now()} {event} host={self.host} pid={self.pid}\n")

    def holder(self, batch_id: str) -> dict | None:
        """The claim on ``batch_id`` (``None``: unclaimed); an unreadable claim file reads as ``{"text": ...}``."""
        text = _read(self._path(batch_id), default=None)
        if text is None:
            return None
        try:
            claim = json.loads(text)
        except json.JSONDecodeError:
            return {"text": text}
        return claim if isinstance(claim, dict) else {"text": text}

    def gone(self, batch_id: str, claim: dict) -> bool:
        """Whether the holder of ``claim`` on ``batch_id`` is gone (module docstring); each call is an observation of
        its heartbeat."""
        if claim.get("machine") == self.machine and isinstance(claim.get("pid"), int):
            if claim["pid"] == self.pid and claim.get("token") not in {c["token"] for c in self.held.values()}:
                return True
            if not _running(claim["pid"]):
                return True
        now = self.clock()
        token, beat = claim.get("token", claim.get("text")), claim.get("beat")
        seen = self._seen.get(batch_id)
        if seen is None or (seen.token, seen.beat) != (token, beat):
            self._seen[batch_id] = _Seen(token, beat, now)
            return False
        return now - seen.since >= self.stale_s

    def take(self, batch_id: str) -> bool:
        """Claim ``batch_id``, taking over a claim whose holder is gone; whether this process holds it now."""
        if batch_id in self.held:
            return True
        with self._lock:
            claim = self.holder(batch_id)
            if claim is not None and not self.gone(batch_id, claim):
                return False
            ours = dict(host=self.host, pid=self.pid, machine=self.machine, token=uuid.uuid4().hex,
                        started=_now(), beat=0)
            _write(self._path(batch_id), ours)
            self.held[batch_id] = ours
            self._seen.pop(batch_id, None)
            self._log(batch_id, "claimed" if claim is None else
                      f"took over (from host={claim.get('host')} pid={claim.get('pid')})")
        return True

    def drop(self, batch_id: str, event: str = "dropped") -> None:
        """Give up the claim on ``batch_id`` (``event``: what the log says, e.g. ``"finished"``)."""
        ours = self.held.pop(batch_id, None)
        if ours is None:
            return
        with self._lock:
            claim = self.holder(batch_id)
            if claim is not None and claim.get("token") == ours["token"]:
                self._path(batch_id).unlink(missing_ok=True)
                self._log(batch_id, event)

    def beat(self) -> None:
        """Raise the heartbeat of every claim held (the thread does this every ``heartbeat_s``)."""
        with self._lock:
            for batch_id, ours in list(self.held.items()):
                claim = self.holder(batch_id)
                if claim is None or claim.get("token") != ours["token"]:
                    self.held.pop(batch_id, None)
                    self.lost.append(batch_id)
                    continue
                ours["beat"] += 1
                _write(self._path(batch_id), ours)

    def _beat_loop(self) -> None:
        while not self._stop.wait(self.heartbeat_s):
            if self.held:
                self.beat()


def _write(path: Path, claim: dict) -> None:
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(claim) + "\n")
    os.replace(tmp, path)
