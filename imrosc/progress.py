"""Progress of the commands that read bags, on stderr when it is a terminal.

A bar counts the bags done out of the bags to read, and says the messages read so far, their
rate, the bags that failed and the time left (from the bags' pace); a bag that fails is named
with its error above the bar as it fails (the command reports it again at the end, as without a
bar). It is drawn only when stderr is a terminal and ``-q`` was not given, so that pipes, logs
and CI output never get it.
"""

from __future__ import annotations

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
        if enabled and total:
            self.bar = click.progressbar(
                length=total, label=label, file=sys.stderr, show_pos=True, show_eta=True
            )
            self.bar.__enter__()

    def __call__(self, bag: Path, messages: int) -> None:
        """One more bag done, ``messages`` read from it."""
        self.messages += messages
        if self.bar is not None:
            if self.messages or self.failures:
                rate = self.messages / max(self.clock() - self.started, 1e-9)
                failed = f", {self.failures} failed" if self.failures else ""
                self.bar.label = (
                    f"{self.label}: {self.messages:,} messages ({rate:,.0f} msg/s){failed}"
                )
            self.bar.update(1)
            if self.bar.pos >= self.bar.length:  # done: the next stage's output starts below
                self.close()

    def failed(self, bag: Path, error: str) -> None:
        """A bag that could not be read: named with its error above the bar."""
        self.failures += 1
        error = error.removeprefix(f"{bag}: ")  # a bag's error may name it already
        if self.bar is not None:
            click.echo(f"\r\x1b[Kfailed: {bag}: {error}", err=True)

    def close(self) -> None:
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
