"""Progress of the commands that read bags, on stderr when it is a terminal.

A bar counts the bags done out of the bags to read, and says the messages read so far, their
rate, the bags that failed and the time left (from the bags' pace); a bag that fails is named
with its error above the bar as it fails (the command reports it again at the end, as without a
bar). It is drawn only when stderr is a terminal and ``-q`` was not given, so that pipes, logs
and CI output never get it.

Within a bag read by the command's own process (one bag, or ``-j 1``), the bag's reader tells
the bar every :data:`EVERY` messages (:func:`reading`), so a long bag shows its messages read
out of those it holds and the time left while it is read; bags read by worker processes move
the bar when they are done.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO

import click

Progress = Callable[[Path, int], None]
"""Called once per bag done, with the messages read from it."""
ProgressFactory = Callable[[int], Progress]
"""Makes the progress of a number of bags to read (known once the bags are found)."""
Reading = Callable[[int, int], None]
"""Hears of ``read`` more messages of a bag whose read selects ``total`` messages."""

EVERY = 4096
"""A bag's reader tells the bar every this many messages."""
REDRAW = 0.25
"""Seconds between two redraws of the bar within a bag."""

_LISTENERS: list[tuple[int, Reading]] = []
"""The drawn bars that hear of messages within a bag (the last one does), each with the
process that draws it."""


def reading(read: int, total: int) -> None:
    """From a bag's reader (:mod:`imrosc.bags`): ``read`` more messages of the ``total`` the
    read selects. Heard by the bar drawn by this very process, if any (a worker process,
    forked from the one that draws it, does not draw)."""
    if _LISTENERS and _LISTENERS[-1][0] == os.getpid():
        _LISTENERS[-1][1](read, total)


def wanted(quiet: bool, stream: TextIO | None = None) -> bool:
    """Whether to draw progress: not ``-q`` and stderr (``stream``) is a terminal."""
    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    return not quiet and callable(isatty) and bool(isatty())


class BagProgress:
    """A progress bar over bags: bags done, messages read, messages per second, ETA."""

    def __init__(self, total: int, label: str, enabled: bool) -> None:
        self.clock = time.monotonic
        self.started = self.clock()
        self.messages = 0
        self.failures = 0
        self.label = label
        self.bar: Any = None
        self.within = 0
        """Messages read of the bag being read (by this process)."""
        self.drawn = self.started
        if enabled and total:
            self.bar = click.progressbar(
                length=total, label=label, file=sys.stderr, show_pos=True, show_eta=True
            )
            self.bar.__enter__()
            _LISTENERS.append((os.getpid(), self.reading))

    def __call__(self, bag: Path, messages: int) -> None:
        """One more bag done, ``messages`` read from it."""
        self.messages += messages
        self.within = 0
        if self.bar is not None:
            if self.messages or self.failures:
                self.bar.label = f"{self.label}: {self._read(self.messages)}"
            self.bar.update(1)
            if self.bar.pos >= self.bar.length:  # done: the next stage's output starts below
                self.close()

    def reading(self, read: int, total: int) -> None:
        """``read`` more messages of the bag being read, which holds ``total`` for the read
        (see :func:`reading`): the label says how far the bag is and its time left."""
        self.within += read
        now = self.clock()
        if self.bar is None or now - self.drawn < REDRAW:
            return
        self.drawn = now
        done = self.messages + self.within
        rate = done / max(now - self.started, 1e-9)
        this = f"{self.within:,} of {total:,} of this bag" if total else f"{self.within:,}"
        left = f", {(total - self.within) / rate:.0f} s left" if total and rate > 0 else ""
        self.bar.label = f"{self.label}: {self._read(done)}; {this}{left}"
        self.bar.render_progress()

    def _read(self, messages: int) -> str:
        """Messages read so far, their rate, and the bags that failed, in words."""
        rate = messages / max(self.clock() - self.started, 1e-9)
        failed = f", {self.failures} failed" if self.failures else ""
        return f"{messages:,} messages ({rate:,.0f} msg/s){failed}"

    def failed(self, bag: Path, error: str) -> None:
        """A bag that could not be read: named with its error above the bar."""
        self.failures += 1
        error = error.removeprefix(f"{bag}: ")  # a bag's error may name it already
        if self.bar is not None:
            click.echo(f"\r\x1b[Kfailed: {bag}: {error}", err=True)

    def close(self) -> None:
        _LISTENERS[:] = [entry for entry in _LISTENERS if entry[1] != self.reading]
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None


@contextmanager
def bag_progress(label: str, quiet: bool) -> Iterator[ProgressFactory]:
    """A factory of progress bars (one per call) for a command, all closed at the end."""
    enabled = wanted(quiet)
    bars: list[BagProgress] = []

    def factory(total: int) -> Progress:
        bars.append(BagProgress(total, label, enabled))
        return bars[-1]

    try:
        yield factory
    finally:
        for bar in bars:
            bar.close()


def bag_done(progress: Progress | None, bag: Path, messages: int, error: str | None = None) -> None:
    """Tell ``progress`` (if any) of a bag done: the messages read from it and, when it
    could not be read, the error (a progress with a ``failed`` method, a bar, hears of it)."""
    if progress is None:
        return
    if error is not None:
        failed = getattr(progress, "failed", None)
        if callable(failed):
            failed(bag, error)
    progress(bag, messages)


def shared(progress: Progress) -> ProgressFactory:
    """A factory that hands out one bar (over every stage of a command) whatever the total."""
    return lambda total: progress


quiet_option = click.option(
    "-q", "--quiet", is_flag=True, help="No progress bar (drawn only when stderr is a terminal)."
)
