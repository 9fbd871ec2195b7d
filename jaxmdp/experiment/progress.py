"""One progress display for every long run: a tqdm bar on a terminal, nothing anywhere else.

A :class:`Progress` counts units of work (the runner's are member-steps, one step of one member; a sweep's are seeds)
and shows, on one line, the fraction done, the rate in units per second and the time left. The runner advances it
after every chunk and announces each program it compiles, with the seconds it took (:func:`jaxmdp.runner.run`); a
caller that runs several runs (the benchmark) makes one display and passes it to every run, so that one bar counts
the work of all of them and moves inside each.

It writes only to a terminal: when its stream is not one (a log file, a pipe, a notebook's captured stream) it writes
nothing but the messages its caller marks for logs (:meth:`Progress.write` with ``log=True``) and makes no tqdm bar
at all, so that logs hold no carriage-return redraws and a library call costs nothing by default; with ``quiet`` it
writes nothing at all. It reads nothing of a run: results are the same with and without it.

The rate and the time left count running only: after a compilation the rate's clock restarts, because compiling a
program takes far longer than a chunk of running and would otherwise make the first estimates of a run meaningless.
The elapsed time stays the wall time.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterator
from types import TracebackType
from typing import TextIO

from tqdm import tqdm

__all__ = ["Progress", "BAR_FORMAT", "is_terminal"]

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
    ) -> None:
        if isinstance(total, bool) or not isinstance(total, int) or total < 0:
            raise ValueError(f"total must be an integer >= 0; got {total!r}")
        if not isinstance(quiet, bool):
            raise ValueError(f"quiet must be True or False; got {quiet!r}")
        self.file = sys.stderr if file is None else file  # the stderr of the moment, not of import time
        self.desc = desc
        self.quiet = quiet
        self._bar: tqdm | None = None
        if not quiet and is_terminal(self.file):
            self._bar = tqdm(
                total=total, desc=desc, unit=f" {unit}", unit_scale=unit_scale, file=self.file,
                bar_format=BAR_FORMAT, mininterval=mininterval, miniters=1, dynamic_ncols=True, leave=True,
            )

    @property
    def enabled(self) -> bool:
        """Whether anything is shown (a terminal, not quiet)."""
        return self._bar is not None

    def update(self, n: int) -> None:
        """``n`` more units done."""
        if self._bar is not None:
            self._bar.update(n)

    def skip(self, n: int) -> None:
        """``n`` units that need no running here (done by an earlier, interrupted call): taken off the total, so that
        the rate and the time left count only the work this call does."""
        if self._bar is not None:
            self._bar.total = max(self._bar.total - n, self._bar.n)
            self._bar.refresh()

    def set_postfix(self, text: str) -> None:
        """Text at the end of the line (e.g. which part of the work is running)."""
        if self._bar is not None:
            self._bar.set_postfix_str(text)

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
        ``compiling <what> ... <seconds> s``; the rate's clock restarts after it (see the module docstring)."""
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
        """End the display (its last line stays)."""
        if self._bar is not None:
            self._bar.close()

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, err: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
