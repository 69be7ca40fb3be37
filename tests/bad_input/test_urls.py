"""Bad bag URLs (imrosc.remote): a URL the server does not have, a host out of reach, a URL
that is not a bag, a protocol whose package is missing. Each is one line naming the URL and
the problem, with the exit status of a local bag with the same problem, and no traceback."""

from __future__ import annotations

import socket
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from imrosc.cli import main
from tests.bad_input.support import project, template
from tests.served import serve

__all__ = ["project", "template"]


@pytest.fixture
def url(project: Path) -> Iterator[str]:
    (project / "bags" / "fake.bag").write_text("not a bag\n")
    with serve(project) as served:
        yield served


def _closed_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def invoke(*arguments: str) -> Result:
    return CliRunner().invoke(main, [*arguments, "-q"])


def lines(result: Result) -> list[str]:
    """What a command said on stderr, less the diagnostics' summary line."""
    return [line for line in result.stderr.splitlines() if not line.startswith("Found ")]


def cases(url: str) -> dict[str, tuple[str, str, str]]:
    """Per case: the URL, the problem said of it, and the local path with the same problem."""
    return {
        "absent": (f"{url}/bags/gone.bag", "not found (HTTP 404)", "bags/gone.bag"),
        "unreachable": (
            f"http://127.0.0.1:{_closed_port()}/r.bag",
            "cannot reach it: Cannot connect to host 127.0.0.1:",
            "bags/gone.bag",
        ),
        "not a bag": (f"{url}/bags/fake.bag", "cannot open bag: ", "bags/fake.bag"),
        "not named as a bag": (
            f"{url}/p.xml",
            "not a bag: expected a .bag file or a folder holding metadata.yaml",
            "p.xml",
        ),
    }


@pytest.mark.parametrize("case", ["absent", "unreachable", "not a bag", "not named as a bag"])
def test_a_bad_url_is_one_line_and_the_status_of_the_same_local_problem(
    project: Path, url: str, case: str
) -> None:
    bad, problem, local = cases(url)[case]
    inv = str(project / "p.inv")
    for command in (["replay", inv], ["info"]):
        remote = invoke(*command, bad)
        same = invoke(*command, str(project / local))
        assert remote.exit_code == same.exit_code != 0
        assert "Traceback" not in remote.output
        said = [line for line in remote.output.splitlines() if bad in line and problem in line]
        assert said, remote.output  # replay's report says a bag it cannot open on stdout
    config = str(project / "p.xml")
    remote = invoke("infer", config, "--bags", bad, "-o", str(project / "x.inv"))
    same = invoke("infer", config, "--bags", str(project / local), "-o", str(project / "y.inv"))
    assert remote.exit_code == same.exit_code != 0
    assert f"{bad}:1:1: error: " in remote.stderr and "Traceback" not in remote.output


def test_a_protocol_without_its_package_says_what_to_install(
    project: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "s3fs", None)
    result = invoke("replay", str(project / "p.inv"), "s3://fleet/run1.bag")
    assert result.exit_code == 2  # no bag read: an input error, as in info
    assert lines(result) == [
        "s3://fleet/run1.bag:1:1: error: reading s3:// URLs needs s3fs: pip install s3fs "
        "(or pip install 'imrosc[s3]') [bag-error]"
    ]
    unknown = invoke("info", "nope://fleet/run1.bag")
    assert unknown.exit_code == 2
    assert lines(unknown) == [
        "imrosc info: nope://fleet/run1.bag:1:1: error: fsspec knows no protocol nope:// "
        "[bag-error]"
    ]
