"""One progress display for every long run: a tqdm bar on a terminal, nothing anywhere else.

A :class:`Progress` counts units of work (the runner's are member-steps, one step of one member; a sweep's are seeds)
and shows, on one line, the fraction done, the rate in units per second and the time left. The runner advances it
after every chunk and announces each program it compiles, with the seconds it took (:func:`jaxmdp.runner.run`); a
caller that runs several runs (the benchmark) makes one display and passes it to every run, so that one bar counts
the work of all of them and moves inside each.

The bar is drawn only on a terminal. When the stream is not one (a log file, a pipe, a notebook's captured stream)
no tqdm bar is made, so that logs hold no carriage-return redraws and a library call costs nothing by default: it
writes the messages its caller marks for logs (:meth:`Progress.write` with ``log=True``) and, only when asked with
``log_every``, a plain progress line at most every ``log_every`` seconds and one at the end, with each compilation's
seconds; that is how a run of hours started with ``nohup ... > log`` shows how far it is and how long it has left
(the benchmark's command asks for a line every five minutes). With ``quiet`` it writes nothing at all. It reads
nothing of a run: results are the same with and without it.

The rate and the time left count running only: after a compilation the rate's clock restarts (the bar; the log lines
take the compilations' seconds off the running time), because compiling a program takes far longer than a chunk of
running and would otherwise make the first estimates of a run meaningless. The elapsed time stays the wall time.
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
from collections.abc import Iterator
from types import TracebackType
from typing import TextIO

from tqdm import tqdm

__all__ = ["Progress", "BAR_FORMAT", "LOG_EVERY_S", "is_terminal"]

#: Seconds between two progress lines in the logs of the long commands (``jaxmdp-benchmark run`` and ``tune``).
LOG_EVERY_S = 300.0

_now = time.monotonic  # the log lines' clock (the tests replace it)

#: The bar's line: description, percentage, bar, done/total units, elapsed and left times, units per second.
BAR_FORMAT = (
    "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt}{unit} "
    "[{elapsed} elapsed, {remaining} left, {rate_noinv_fmt}{postfix}]"
)


def is_terminal(stream: object) -> bool:
    """Whether ``stream`` is an open terminal (its ``isatty()`` says so)."""
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty()) if callable(isatty) else False
    except ValueError:  # a closed file
        return False


class Progress:
    """A progress bar of ``total`` units of work on ``file`` (default: ``sys.stderr`` when the display is made).

    Args:
      total: units of work to do (>= 0).
      desc: what is running (the start of the line).
      unit: the units' name, plural (``"member-steps"``, ``"seeds"``).
      file: the stream; the display is shown only when it is a terminal (:func:`is_terminal`).
      quiet: show nothing whatever the stream.
      unit_scale: write large counts and rates with SI prefixes (``4.50M``); off for counts that stay small.
      mininterval: seconds between two redraws at least (tqdm's; ``0`` redraws at every update).
      log_every: when the stream is not a terminal, write a progress line (done/total, elapsed and left times, rate)
        at most every ``log_every`` seconds, at the first update past each interval, and one at :meth:`close`;
        ``None`` (default): no progress lines in logs.

    Use it as a context manager (or call :meth:`close`): the bar's last state stays on the screen.
    """

    def __init__(
        self,
        total: int,
        desc: str = "",
        unit: str = "member-steps",
        *,
        file: TextIO | None = None,
        quiet: bool = False,
        unit_scale: bool = True,
        mininterval: float = 0.1,
        log_every: float | None = None,
    ) -> None:
        if isinstance(total, bool) or not isinstance(total, int) or total < 0:
            raise ValueError(f"total must be an integer >= 0; got {total!r}")
        if not isinstance(quiet, bool):
            raise ValueError(f"quiet must be True or False; got {quiet!r}")
        if log_every is not None and (isinstance(log_every, bool) or not isinstance(log_every, (int, float))
                                      or not 0 < log_every < math.inf):
            raise ValueError(f"log_every must be a positive number of seconds or None; got {log_every!r}")
        self.file = sys.stderr if file is None else file  # the stderr of the moment, not of import time
        self.desc = desc
        self.quiet = quiet
        self._bar: tqdm | None = None
        self._lines: _LogLines | None = None
        if not quiet and is_terminal(self.file):
            self._bar = tqdm(
                total=total, desc=desc, unit=f" {unit}", unit_scale=unit_scale, file=self.file,
                bar_format=BAR_FORMAT, mininterval=mininterval, miniters=1, dynamic_ncols=True, leave=True,
            )
        elif not quiet and log_every is not None:
            self._lines = _LogLines(total, desc, unit, unit_scale, float(log_every), self.file)

    @property
    def enabled(self) -> bool:
        """Whether progress is shown (a bar on a terminal, or lines in a log with ``log_every``; not quiet)."""
        return self._bar is not None or self._lines is not None

    def update(self, n: int) -> None:
        """``n`` more units done."""
        if self._bar is not None:
            self._bar.update(n)
        elif self._lines is not None:
            self._lines.update(n)

    def skip(self, n: int) -> None:
        """``n`` units that need no running here (done by an earlier, interrupted call): taken off the total, so that
        the rate and the time left count only the work this call does."""
        if self._bar is not None:
            self._bar.total = max(self._bar.total - n, self._bar.n)
            self._bar.refresh()
        elif self._lines is not None:
            self._lines.total = max(self._lines.total - n, self._lines.n)

    def set_postfix(self, text: str) -> None:
        """Text at the end of the line (e.g. which part of the work is running)."""
        if self._bar is not None:
            self._bar.set_postfix_str(text)
        elif self._lines is not None:
            self._lines.postfix = text

    def write(self, line: str, *, log: bool = False) -> None:
        """A line above the bar (the bar is redrawn below it). ``log=True``: a message worth keeping in a log, written
        to the stream even when it is not a terminal (never when ``quiet``)."""
        if self._bar is not None:
            self._bar.write(line, file=self.file)
        elif log and not self.quiet:
            print(line, file=self.file, flush=True)

    @contextlib.contextmanager
    def compiling(self, what: str) -> Iterator[None]:
        """Announce ``compiling <what> ...`` on the bar's line while the block runs, then write the line
        ``compiling <what> ... <seconds> s``; the rate's clock restarts after it (see the module docstring). In a log
        with ``log_every``: the line, its seconds taken off the running time."""
        if self._lines is not None:
            start = _now()
            yield
            seconds = _now() - start
            self._lines.compiled(seconds)
            print(f"compiling {what} ... {seconds:.1f} s", file=self.file, flush=True)
            return
        if self._bar is None:
            yield
            return
        clock = getattr(self._bar, "_time", time.time)  # the bar's clock (wall time)
        label = f"compiling {what} ..."
        self._bar.set_description_str(f"{self.desc}, {label}" if self.desc else label)
        start = clock()
        try:
            yield
        finally:
            self._bar.set_description_str(self.desc, refresh=False)
        self.write(f"{label} {clock() - start:.1f} s")
        # tqdm measures its rate between two redraws: the interval of the next one starts now, after compiling.
        self._bar.last_print_t = clock()

    def close(self) -> None:
        """End the display (its last line stays; in a log, a last progress line unless nothing ran)."""
        if self._bar is not None:
            self._bar.close()
        elif self._lines is not None:
            self._lines.close()

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, err: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


class _LogLines:
    """The progress lines of a :class:`Progress` in a log: plain lines, no redraws, at most one every ``every``
    seconds. The rate is the units done per second of running (wall time since the display was made, less the
    compilations'); the time left is the units left at that rate."""

    def __init__(self, total: int, desc: str, unit: str, unit_scale: bool, every: float, file: TextIO) -> None:
        self.total, self.desc, self.unit, self.unit_scale = total, desc, unit, unit_scale
        self.every, self.file = every, file
        self.n = 0
        self.postfix = ""
        self.start = self.last = _now()
        self.compiling_s = 0.0
        self.shown_n: int | None = None

    def compiled(self, seconds: float) -> None:
        self.compiling_s += seconds

    def update(self, n: int) -> None:
        self.n += n
        if _now() - self.last >= self.every:
            self.show()

    def close(self) -> None:
        if self.n and self.shown_n != self.n:
            self.show()

    def _count(self, x: float) -> str:
        return tqdm.format_sizeof(x, divisor=1000) if self.unit_scale else f"{x:g}"

    def show(self) -> None:
        now = self.last = _now()
        self.shown_n = self.n
        running = now - self.start - self.compiling_s
        rate = self.n / running if running > 0 else 0.0
        left = tqdm.format_interval((self.total - self.n) / rate) if rate > 0 else "?"  # no rate yet
        share = 100.0 * self.n / self.total if self.total else 100.0
        postfix = f", {self.postfix}" if self.postfix else ""
        print(f"{self.desc + ': ' if self.desc else ''}{share:3.0f}% {self._count(self.n)}/{self._count(self.total)} "
              f"{self.unit} [{tqdm.format_interval(now - self.start)} elapsed, {left} left, "
              f"{self._count(rate) if rate > 0 else '?'} {self.unit}/s{postfix}]", file=self.file, flush=True)
