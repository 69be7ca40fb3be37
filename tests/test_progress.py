"""Progress on every command that reads bags (issue 18, item 7): drawn on stderr only when it
is a terminal, never with ``-q``; ``-q`` is accepted everywhere."""

from __future__ import annotations

import os
import pty
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc import progress as progress_module
from imrosc.bags import open_bag
from imrosc.cli import main
from imrosc.progress import BagProgress, bag_done, reading, wanted
from tests.bad_input.support import project, template

__all__ = ["project", "template"]

ROOT = Path(__file__).resolve().parent.parent
BAGS = ("{d}/bags/train/r1.bag", "{d}/bags/ok/s1.bag", "{d}/bags/bad/f1.bag")
COMMANDS: dict[str, tuple[str, ...]] = {
    "infer": ("infer", "{d}/p.xml", "-j", "1"),
    "replay": ("replay", "{d}/p.inv", *BAGS),
    "classify": ("classify", "{d}/p.xml", "-j", "1"),
    "stability": ("stability", "{d}/p.xml", "-j", "1"),
    "info": ("info", *BAGS),
    "export-daikon": ("export-daikon", "{d}/p.xml", "-o", "{d}/daikon"),
    "graph": ("graph", *BAGS),
    "build": ("build", "{d}/p.xml", "--bags", "{d}/bags/train", "-o", "{d}/build", "--force"),
}
LABELS = ("inferring", "replaying", "classifying", "cross-validating", "reading", "exporting")


def args_of(command: str, folder: Path) -> list[str]:
    return [arg.replace("{d}", str(folder)) for arg in COMMANDS[command]]


@pytest.mark.parametrize("quiet", [True, False], ids=["-q", "no -q"])
@pytest.mark.parametrize("command", list(COMMANDS))
def test_no_progress_when_stderr_is_not_a_terminal(
    command: str, quiet: bool, project: Path
) -> None:
    args = args_of(command, project) + (["-q"] if quiet else [])
    result = CliRunner().invoke(main, args)
    assert result.exit_code in (0, 1, 3, 5), result.output  # -q is an option of each
    assert "Traceback" not in result.output
    assert not any(label in result.stderr for label in LABELS), result.stderr


def on_a_terminal(args: list[str], cwd: Path) -> tuple[int, str]:
    """Run ``imrosc ARGS`` with stderr on a pseudo-terminal; its status and stderr."""
    master, slave = pty.openpty()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    process = subprocess.Popen(
        [sys.executable, "-m", "imrosc", *args],
        stdout=subprocess.DEVNULL,
        stderr=slave,
        cwd=cwd,
        env=env,
    )
    os.close(slave)
    seen = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # the other end closed
            break
        if not chunk:
            break
        seen += chunk
    os.close(master)
    return process.wait(timeout=120), seen.decode(errors="replace")


@pytest.mark.parametrize("command", ["replay", "info", "build"])
def test_progress_on_a_terminal_and_not_with_q(command: str, project: Path) -> None:
    status, drawn = on_a_terminal(args_of(command, project), project)
    assert status in (0, 1), drawn  # f1.bag is a failed run: replay may alarm
    label = "replaying" if command == "replay" else "reading"
    if command == "build":  # the graph of the bags: callerids, no message read
        assert label in drawn and "2/2" in drawn, drawn
    else:
        assert f"{label}: 240 messages (" in drawn and "3/3" in drawn, drawn
    status, quiet = on_a_terminal([*args_of(command, project), "-q"], project)
    assert status in (0, 1) and label not in quiet, quiet


def test_a_bar_counts_bags_and_messages() -> None:
    bar = BagProgress(2, "reading", enabled=False)
    bar(Path("a.bag"), 10)
    bag_done(bar, Path("b.bag"), 5)
    bag_done(bar, Path("c.bag"), 0, "c.bag: cannot open bag")
    bar.close()
    assert bar.messages == 15 and bar.failures == 1 and bar.bar is None


def test_a_bag_that_fails_is_named_with_its_error_as_it_fails(project: Path) -> None:
    (project / "notes.bag").write_text("not a bag\n")
    status, drawn = on_a_terminal(
        [*args_of("replay", project), str(project / "notes.bag")], project
    )
    assert status == 1, drawn
    assert f"failed: {project / 'notes.bag'}: cannot open bag: not a ROS 1 bag" in drawn, drawn
    assert "msg/s), 1 failed" in drawn and "4/4" in drawn, drawn


def test_progress_is_wanted_only_on_a_terminal_without_q() -> None:
    class Terminal:
        def isatty(self) -> bool:
            return True

    assert wanted(False, Terminal())  # type: ignore[arg-type]
    assert not wanted(True, Terminal())  # type: ignore[arg-type]
    assert not wanted(False, open(os.devnull, "w"))  # noqa: SIM115


@pytest.mark.slow
def test_the_demo_shows_progress_on_a_terminal_and_not_with_q(tmp_path: Path) -> None:
    """The demo reads bags in four stages (build's graph, infer, classify, stability)."""
    args = ["demo", "-o", str(tmp_path / "demo"), "--runs", "2", "-j", "1"]
    status, drawn = on_a_terminal(args, tmp_path)
    assert status == 0, drawn
    assert "reading: " in drawn and " messages (" in drawn and "2/2" in drawn, drawn
    status, quiet = on_a_terminal([*args, "-q"], tmp_path)
    assert status == 0 and "reading" not in quiet and "msg/s" not in quiet, quiet


def test_a_long_bag_moves_the_bar_while_it_is_read(monkeypatch: pytest.MonkeyPatch) -> None:
    """Within a bag the reader tells the drawn bar every EVERY messages: the label says the
    messages read of the bag's and the time left; redrawn at most every REDRAW seconds."""
    now = [100.0]
    monkeypatch.setattr(time, "monotonic", lambda: now[0])
    bar = BagProgress(1, "replaying", enabled=True)
    try:
        assert bar.bar is not None
        now[0] += 2.0
        reading(4000, 10_000)
        assert (
            bar.bar.label == "replaying: 4,000 messages (2,000 msg/s); 4,000 of 10,000 "
            "of this bag, 3 s left"
        )
        now[0] += 0.1  # too soon to draw again
        reading(1000, 10_000)
        assert "4,000 of 10,000" in bar.bar.label and bar.within == 5000
        now[0] += 0.5
        bar(Path("a.bag"), 10_000)
        assert bar.within == 0 and bar.bar is None  # the last bag: done and closed
        reading(10, 10)  # no bar listens any more
    finally:
        bar.close()


def test_only_the_process_that_draws_the_bar_hears_of_messages() -> None:
    heard: list[tuple[int, int]] = []
    progress_module._LISTENERS.append((os.getpid() + 1, lambda r, t: heard.append((r, t))))
    try:
        reading(5, 9)  # a forked worker's pid is not the drawing process's
        assert heard == []
    finally:
        progress_module._LISTENERS.pop()


def test_the_bag_reader_tells_the_bar_every_so_many_messages(
    project: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    heard: list[tuple[int, int]] = []
    monkeypatch.setattr(progress_module, "EVERY", 30)
    monkeypatch.setattr(
        progress_module, "_LISTENERS", [(os.getpid(), lambda r, t: heard.append((r, t)))]
    )
    with open_bag(project / "bags" / "train" / "r1.bag") as reader:
        read = sum(1 for _ in reader.messages())
    assert read == 80 and heard == [(30, 80), (30, 80)]
