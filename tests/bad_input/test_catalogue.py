"""The catalogue of bad inputs and hostile environments (issue 18): one row per case.

Each row runs one command as a user would, in a fresh copy of a small project (a
configuration, training, successful and failed bags, the invariants learnt from them), and
asserts the exit status of its class (README, "Exit status": 2 usage and input errors, refused
outputs included; 4 the system refused a write), the one line on stderr naming the file and
the problem, no traceback, and that no file that was there before changed.

Permission denied and a full disk are simulated (the tests may run as root, which no
permission stops): the write of the temporary file raises the ``OSError`` the system would.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from imrosc import outputs
from imrosc.cli import main
from tests.bad_input.support import CONFIG, project, snapshot, template
from tests.record.support import CONFIG as RECORD_CONFIG

__all__ = ["project", "template"]

USAGE, ENVIRONMENT = 2, 4


# -- setups: what a row does to the project before the command ------------------------------


def user_file(name: str, text: str = "my notes\n") -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text)

    return setup


def copy_inv(name: str) -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        shutil.copyfile(folder / "p.inv", folder / name)

    return setup


def dangling(name: str) -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        (folder / name).symlink_to(folder / "nowhere" / "target")

    return setup


def report_file(name: str) -> Callable[[Path], None]:
    text = json.dumps({"$comment": f"{outputs.mark(outputs.REPORT)} (imrosc replay)"})
    return user_file(name, text + "\n")


def edited_inv(name: str, edit: Callable[[dict[str, Any]], Any]) -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        document = json.loads((folder / "p.inv").read_text())
        edit(document)
        (folder / name).write_text(json.dumps(document))

    return setup


def raw_inv(name: str, text: Callable[[Path], str]) -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        (folder / name).write_text(text(folder))

    return setup


def _first(document: dict[str, Any]) -> dict[str, Any]:
    first: dict[str, Any] = document["invariants"][0]
    return first


def _bound(document: dict[str, Any]) -> dict[str, Any]:
    return next(i for i in document["invariants"] if i["family"] == "bounds")


def _huge_int(folder: Path) -> str:
    """An integer of 5,000 digits (Python's json refuses more than 4,300)."""
    return (folder / "p.inv").read_text().replace('"samples": ', '"samples": ' + "1" * 5000, 1)


def _nested(folder: Path) -> str:
    document = json.loads((folder / "p.inv").read_text())
    marker = "NESTED"
    document["points"]["a"]["extra"] = marker
    return json.dumps(document).replace(f'"{marker}"', "[" * 100_000 + "]" * 100_000)


def _huge_bound(document: dict[str, Any]) -> None:
    _bound(document)["params"]["min"] = 10**400


def _no_point(document: dict[str, Any]) -> None:
    del _first(document)["point"]


def _params_list(document: dict[str, Any]) -> None:
    _first(document)["params"] = []


def _unknown_point(document: dict[str, Any]) -> None:
    _first(document)["point"] = "zz"


def _unknown_family(document: dict[str, Any]) -> None:
    _first(document)["family"] = "boundz"


def _bad_variables(document: dict[str, Any]) -> None:
    document["points"]["a"]["variables"] = "out.data"


def _text_bound(document: dict[str, Any]) -> None:
    _bound(document)["params"]["min"] = "abc"


def record_project(folder: Path) -> None:
    """A configuration with a service to record and a launch file that starts its server."""
    (folder / "robot.xml").write_text(RECORD_CONFIG)
    (folder / "robot.launch").write_text(
        '<launch>\n  <node pkg="robot" type="server" name="server" ns="a"/>\n</launch>\n'
    )


# -- what the system does: simulated failures ------------------------------------------------


def _no_master(monkeypatch: pytest.MonkeyPatch) -> None:
    """ROS 1 without a master (the launch copy is written before the master is needed)."""
    monkeypatch.setenv("ROS_MASTER_URI", "http://127.0.0.1:9")
    monkeypatch.delenv("ROS_VERSION", raising=False)


def _denied_in(folder: str) -> Callable[[pytest.MonkeyPatch], None]:
    """Writing is denied in ``folder`` alone (the others stay writable): ``os.access``
    says so, as it would to a user without the right."""

    def system(monkeypatch: pytest.MonkeyPatch) -> None:
        real = os.access

        def access(path: Any, mode: int, *args: Any, **kwargs: Any) -> bool:
            if mode & os.W_OK and os.path.basename(os.fspath(path)) == folder:
                return False
            return real(path, mode, *args, **kwargs)

        monkeypatch.setattr(os, "access", access)

    return system


def _no_space(monkeypatch: pytest.MonkeyPatch) -> None:
    real = os.fdopen

    class Full:
        def __init__(self, stream: Any) -> None:
            self.stream = stream

        def __enter__(self) -> Full:
            return self

        def __exit__(self, *args: Any) -> None:
            self.stream.close()

        def write(self, data: Any) -> int:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def __getattr__(self, name: str) -> Any:
            return getattr(self.stream, name)

    monkeypatch.setattr(os, "fdopen", lambda *a, **k: Full(real(*a, **k)))


def _denied(monkeypatch: pytest.MonkeyPatch) -> None:
    def mkstemp(*args: Any, dir: str | None = None, **kwargs: Any) -> Any:
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(dir))

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    real_mkdir = Path.mkdir

    def mkdir(self: Path, *args: Any, **kwargs: Any) -> None:
        if "demo" in str(self):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(self))
        real_mkdir(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", mkdir)


@dataclass(frozen=True)
class Case:
    """One row: the command line (``{d}`` is the project folder), what is set up first and
    simulated, the exit status, a fragment of the one line on stderr, and files that must
    not come into being."""

    args: tuple[str, ...]
    status: int
    message: str
    setup: Callable[[Path], None] | None = None
    system: Callable[[pytest.MonkeyPatch], None] | None = None
    absent: tuple[str, ...] = field(default=())


INV, XML, BAG = "{d}/p.inv", "{d}/p.xml", "{d}/bags/train/r1.bag"
RECORD = (
    "record",
    "{d}/robot.xml",
    "-o",
    "{d}/rec",
    "--launch",
    "{d}/robot.launch",
    "--server",
    "/task=/a/server",
    "--launch-out",
)
CLASSIFY = ("classify", XML, "-j", "1")
STABILITY = ("stability", XML, "-j", "1")
INFER = ("infer", XML, "-j", "1", "-q")

CASES: dict[str, Case] = {
    # -- outputs never destroy each other -------------------------------------------------
    "replay -o onto its invariants": Case(
        ("replay", INV, BAG, "--format", "html", "-o", INV),
        USAGE,
        "p.inv: is an input of this command",
    ),
    "replay -o onto its bag": Case(
        ("replay", INV, BAG, "-o", BAG), USAGE, "r1.bag: is an input of this command"
    ),
    "replay -o onto another invariants file": Case(
        ("replay", INV, BAG, "--format", "json", "-o", "{d}/other.inv"),
        USAGE,
        "other.inv: is an imrosc invariants file, not a report file; use --force",
        setup=copy_inv("other.inv"),
    ),
    "replay -o onto a user's file": Case(
        ("replay", INV, BAG, "-o", "{d}/notes.txt"),
        USAGE,
        "notes.txt: exists and was not generated by imrosc; use --force",
        setup=user_file("notes.txt"),
    ),
    "replay -o through a dangling link": Case(
        ("replay", INV, BAG, "-o", "{d}/link.html"),
        USAGE,
        "link.html: is a dangling symbolic link",
        setup=dangling("link.html"),
        absent=("nowhere",),
    ),
    "classify --refined onto its source": Case(
        (*CLASSIFY, "--refined", INV), USAGE, "p.inv: is an input of this command"
    ),
    "classify refuses its report before writing the refined file": Case(
        (*CLASSIFY, "--refined", "{d}/new.inv", "-o", "{d}/notes.txt"),
        USAGE,
        "notes.txt: exists and was not generated by imrosc; use --force",
        setup=user_file("notes.txt"),
        absent=("new.inv",),
    ),
    "classify report and refined file the same": Case(
        (*CLASSIFY, "--refined", "{d}/same.inv", "-o", "{d}/same.inv"),
        USAGE,
        "same.inv: is also the refined invariants file",
        absent=("same.inv",),
    ),
    "classify onto a user's file at the default refined path": Case(
        CLASSIFY,
        USAGE,
        "p.refined.inv: exists and was not generated by imrosc; use --force",
        setup=user_file("p.refined.inv"),
    ),
    "classify -o onto its configuration": Case(
        (*CLASSIFY, "-o", XML), USAGE, "p.xml: is an input of this command"
    ),
    "infer -o onto a report": Case(
        (*INFER, "-o", "{d}/r.json"),
        USAGE,
        "r.json: is an imrosc report file, not an invariants file; use --force",
        setup=report_file("r.json"),
    ),
    "infer onto a user's file at the default path": Case(
        INFER,
        USAGE,
        "p.inv: exists and was not generated by imrosc; use --force",
        setup=user_file("p.inv"),
    ),
    "infer -o onto a training bag": Case(
        (*INFER, "-o", BAG), USAGE, "r1.bag: is an input of this command"
    ),
    "infer -o onto its configuration": Case(
        (*INFER, "-o", XML), USAGE, "p.xml: is an input of this command"
    ),
    "stability -o onto its configuration": Case(
        (*STABILITY, "-o", XML), USAGE, "p.xml: is an input of this command"
    ),
    "stability -o onto a <detect> bag, forced": Case(
        (*STABILITY, "-o", BAG, "--force"), USAGE, "r1.bag: is an input of this command"
    ),
    "export-daikon onto the user's .decls": Case(
        ("export-daikon", XML, "-o", "{d}/daikon"),
        USAGE,
        "imrosc.decls: exists and was not generated by imrosc; use --force",
        setup=user_file("daikon/imrosc.decls", "decl-version 2.0\n// mine\n"),
        absent=("daikon/000-r1.bag.dtrace",),
    ),
    "export-daikon onto the user's .dtrace": Case(
        ("export-daikon", XML, "-o", "{d}/daikon"),
        USAGE,
        "001-r2.bag.dtrace: exists and was not generated by imrosc; use --force",
        setup=user_file("daikon/001-r2.bag.dtrace", "a:::POINT\n"),
        absent=("daikon/imrosc.decls",),
    ),
    "record --launch-out onto its launch file, forced": Case(
        (*RECORD, "{d}/robot.launch", "--force"),
        USAGE,
        "robot.launch: is an input of this command",
        record_project,
        _no_master,
    ),
    "record --launch-out onto its configuration, forced": Case(
        (*RECORD, "{d}/robot.xml", "--force"),
        USAGE,
        "robot.xml: is an input of this command",
        record_project,
        _no_master,
    ),
    "record --launch-out onto an invariants file": Case(
        (*RECORD, INV),
        USAGE,
        "p.inv: is an imrosc invariants file, not a launch file; use --force",
        record_project,
        _no_master,
    ),
    # -- a full disk: the previous file stays whole ----------------------------------------
    "infer on a full disk": Case(
        INFER, ENVIRONMENT, "p.inv: No space left on device", None, _no_space
    ),
    "replay on a full disk": Case(
        ("replay", INV, BAG, "-o", "{d}/r.html", "--format", "html"),
        ENVIRONMENT,
        "r.html: No space left on device",
        None,
        _no_space,
        ("r.html",),
    ),
    "classify on a full disk": Case(
        CLASSIFY, ENVIRONMENT, "p.refined.inv: No space left on device", None, _no_space
    ),
    "stability on a full disk": Case(
        (*STABILITY, "-o", "{d}/s.json", "--format", "json"),
        ENVIRONMENT,
        "s.json: No space left on device",
        None,
        _no_space,
        ("s.json",),
    ),
    "export-daikon on a full disk": Case(
        ("export-daikon", XML, "-o", "{d}/daikon"),
        ENVIRONMENT,
        "imrosc.decls: No space left on device",
        None,
        _no_space,
        ("daikon/imrosc.decls",),
    ),
    "demo on a full disk": Case(
        ("demo", "-o", "{d}/demo"),
        ENVIRONMENT,
        ".imrosc-demo: No space left on device",
        None,
        _no_space,
    ),
    # -- permission denied ----------------------------------------------------------------
    "infer where writing is denied": Case(INFER, ENVIRONMENT, ": Permission denied", None, _denied),
    "replay where writing is denied": Case(
        ("replay", INV, BAG, "-o", "{d}/r.txt"), ENVIRONMENT, ": Permission denied", None, _denied
    ),
    "classify where writing is denied": Case(
        CLASSIFY, ENVIRONMENT, ": Permission denied", None, _denied
    ),
    "classify -o where writing is denied writes no refined file": Case(
        (*CLASSIFY, "-o", "{d}/reports/r.txt"),
        ENVIRONMENT,
        "reports: Permission denied",
        user_file("reports/notes.txt"),
        _denied_in("reports"),
        ("p.refined.inv", "reports/r.txt"),
    ),
    "stability where writing is denied": Case(
        (*STABILITY, "-o", "{d}/s.txt"), ENVIRONMENT, ": Permission denied", None, _denied
    ),
    "export-daikon where writing is denied": Case(
        ("export-daikon", XML, "-o", "{d}/daikon"),
        ENVIRONMENT,
        ": Permission denied",
        None,
        _denied,
    ),
    "demo where writing is denied": Case(
        ("demo", "-o", "{d}/demo"), ENVIRONMENT, "demo: Permission denied", None, _denied
    ),
    # -- -o under a regular file ------------------------------------------------------------
    "infer -o under a file": Case(
        (*INFER, "-o", "{d}/p.xml/x.inv"), ENVIRONMENT, "p.xml: Not a directory"
    ),
    "replay -o under a file": Case(
        ("replay", INV, BAG, "-o", "{d}/p.xml/r.txt"), ENVIRONMENT, "p.xml: Not a directory"
    ),
    "classify --refined under a file": Case(
        (*CLASSIFY, "--refined", "{d}/p.xml/r.inv"), ENVIRONMENT, "p.xml: Not a directory"
    ),
    "classify -o under a file writes no refined file": Case(
        (*CLASSIFY, "-o", "{d}/p.xml/r.txt"),
        ENVIRONMENT,
        "p.xml: Not a directory",
        absent=("p.refined.inv",),
    ),
    "stability -o under a file": Case(
        (*STABILITY, "-o", "{d}/p.xml/s.txt"), ENVIRONMENT, "p.xml: Not a directory"
    ),
    "export-daikon -o under a file": Case(
        ("export-daikon", XML, "-o", "{d}/p.xml/daikon"), ENVIRONMENT, "Not a directory"
    ),
    "demo -o under a file": Case(("demo", "-o", "{d}/p.xml/demo"), ENVIRONMENT, "Not a directory"),
}

CASES["show --family of no family"] = Case(
    ("show", INV, "--family", "boundz"), USAGE, "p.inv: unknown family 'boundz' (families: bounds,"
)
CASES["show --point of no point"] = Case(
    ("show", INV, "--point", "zz"), USAGE, "p.inv: no point 'zz' in the file (points: a)"
)

MALFORMED: dict[str, tuple[Callable[[Path], None], str]] = {
    "a missing key": (edited_inv("bad.inv", _no_point), "$.invariants[0]: missing 'point'"),
    "a wrong type": (edited_inv("bad.inv", _params_list), "$.invariants[0].params: not an object"),
    "variables not an array": (
        edited_inv("bad.inv", _bad_variables),
        "$.points.a.variables: not an array",
    ),
    "an unknown point": (edited_inv("bad.inv", _unknown_point), "no point 'zz' in 'points'"),
    "an unknown family": (edited_inv("bad.inv", _unknown_family), "unknown family 'boundz'"),
    "a huge number": (edited_inv("bad.inv", _huge_bound), ".params.min: number too large"),
    "a parameter of a wrong type": (
        edited_inv("bad.inv", _text_bound),
        "]: ValueError: could not convert string to float: 'abc'",
    ),
    "a huge integer literal": (raw_inv("bad.inv", _huge_int), "not JSON: Exceeds the limit"),
    "deeply nested JSON": (raw_inv("bad.inv", _nested), "nested too deeply"),
}
for _name, (_setup, _message) in MALFORMED.items():
    CASES[f"show: {_name}"] = Case(("show", "{d}/bad.inv"), USAGE, _message, _setup)
    CASES[f"replay: {_name}"] = Case(("replay", "{d}/bad.inv", BAG), USAGE, _message, _setup)
    CASES[f"classify: {_name}"] = Case(
        (*CLASSIFY, "--inv", "{d}/bad.inv", "--refined", "{d}/r.inv"),
        USAGE,
        _message,
        _setup,
        absent=("r.inv",),
    )


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input(
    name: str, project: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    case = CASES[name]
    if case.setup is not None:
        case.setup(project)
    before = snapshot(project)
    monkeypatch.chdir(tmp_path)
    if case.system is not None:
        case.system(monkeypatch)
    args = [arg.replace("{d}", str(project)) for arg in case.args]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == case.status, (result.exit_code, result.output)
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    assert "Traceback" not in result.output
    lines = result.stderr.splitlines()
    (line,) = [text for text in lines if text.startswith("imrosc ")]
    assert line.startswith(f"imrosc {args[0]}: ") and case.message in line, line
    after = snapshot(project)
    assert {k: v for k, v in after.items() if k in before} == before  # nothing changed
    created = set(after) - set(before)
    assert not [path for path in created if path.endswith(".tmp")]
    for path in case.absent:
        assert not (project / path).exists(), path


def test_export_daikon_overwrites_the_users_files_with_force(project: Path) -> None:
    (project / "daikon").mkdir()
    (project / "daikon" / "imrosc.decls").write_text("mine\n")
    args = ["export-daikon", str(project / "p.xml"), "-o", str(project / "daikon")]
    done = CliRunner().invoke(main, [*args, "--force"])
    assert done.exit_code == 0, done.output
    decls = (project / "daikon" / "imrosc.decls").read_text()
    assert decls.startswith("decl-version 2.0\n") and "[daikon]" in decls
    again = CliRunner().invoke(main, args)  # its own files now: no --force needed
    assert again.exit_code == 0, again.output


def test_the_plan_backend_never_writes_outside_its_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    work = tmp_path / "a" / "b" / "work"
    work.mkdir(parents=True)
    config = work / "c.xml"
    config.write_text(CONFIG.replace('project="p"', 'project="../../x"'))
    monkeypatch.chdir(work)
    done = CliRunner().invoke(main, ["build", str(config)])
    assert done.exit_code == 0, done.output
    written = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*.json"))
    assert written == ["a/b/work/build/x-plan/job.json", "a/b/work/build/x-plan/plan.json"]


def test_a_live_link_is_followed_and_kept(project: Path) -> None:
    (project / "reports").mkdir()
    real = project / "reports" / "r.json"
    real.write_text(json.dumps({"$comment": outputs.mark(outputs.REPORT)}))
    link = project / "r.json"
    link.symlink_to(real)
    args = ["replay", str(project / "p.inv"), str(project / "bags/ok/s1.bag"), "--format", "json"]
    done = CliRunner().invoke(main, [*args, "-o", str(link)])
    assert done.exit_code in (0, 1, 3) and f"wrote {link}" in done.output, done.output
    assert link.is_symlink() and json.loads(real.read_text())["format"] == "imrosc-replay"


def test_a_failed_write_leaves_no_temporary_file(tmp_path: Path) -> None:
    target = tmp_path / "x.inv"
    target.write_bytes(b"old")

    def broken(stream: Any) -> None:
        stream.write(b"half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(OSError, match=r"x\.inv"):
        outputs.write_atomic(target, broken)
    assert target.read_bytes() == b"old" and os.listdir(tmp_path) == ["x.inv"]


def test_a_folder_refusing_the_temporary_file_names_the_target(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def mkstemp(*args: Any, dir: str, prefix: str, suffix: str, **kwargs: Any) -> Any:
        temporary = os.path.join(dir, f"{prefix}abc{suffix}")
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), temporary)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    with pytest.raises(OSError) as raised:
        outputs.write_atomic(tmp_path / "x.inv", b"new")
    assert raised.value.filename == str(tmp_path / "x.inv")
    assert raised.value.errno == errno.EROFS


@pytest.mark.parametrize(
    "args",
    [
        ("check",),
        ("build",),
        ("infer", "-q"),
        ("export-daikon", "-o", "out"),
        ("classify",),
        ("stability",),
    ],
    ids=lambda args: args[0],
)
def test_a_missing_configuration_is_an_input_error_everywhere(
    args: tuple[str, ...], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(main, [args[0], str(tmp_path / "missing.xml"), *args[1:]])
    assert result.exit_code == USAGE, result.output
    assert "missing.xml:1:1: error: cannot read file" in result.output
    assert "Traceback" not in result.output and not list(tmp_path.iterdir())


def test_build_refuses_to_overwrite_another_kind_of_imrosc_file(project: Path) -> None:
    out = project / "build"
    out.mkdir()
    shutil.copyfile(project / "p.inv", out / "plan.json")
    before = snapshot(project)
    result = CliRunner().invoke(main, ["build", str(project / "p.xml"), "-o", str(out)])
    assert result.exit_code == USAGE
    assert "plan.json: is an imrosc invariants file, not a build file; use --force" in (
        result.stderr
    )
    assert snapshot(project) == before


MONITOR = '  <monitor inv="p.inv"><block>/out</block></monitor>\n'
MONITORED = CONFIG.replace("</imROS>", MONITOR + "</imROS>")


@pytest.mark.parametrize("backend", ["ros1", "ros2"])
@pytest.mark.parametrize("name", ["missing", *MALFORMED])
def test_build_refuses_a_bad_invariants_file_as_an_input_error(
    name: str, backend: str, project: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The invariants file a monitor deploys is an input: missing or malformed, it stops
    ``build`` with exit 2 (README, "Exit status"), its name and problem on one line."""
    (project / "m.xml").write_text(MONITORED)
    message = "cannot read: No such file or directory"
    if name != "missing":
        setup, message = MALFORMED[name]
        setup(project)
    before = snapshot(project)
    monkeypatch.chdir(project)
    args = ["build", "m.xml", "--backend", backend, "--inv", "bad.inv", "-o", "pkg"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == USAGE, result.output
    assert "Traceback" not in result.output
    (line,) = [text for text in result.stderr.splitlines() if "[invariants-unreadable]" in text]
    assert "bad.inv" in line and message in line, line
    assert snapshot(project) == before


@pytest.mark.parametrize("command", ["build", "record"])
def test_a_launch_file_that_cannot_be_read_is_an_input_error(
    command: str, project: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The system's launch file, missing: exit 2 (README, "Exit status"), one diagnostic
    naming it; a launch file that is not roslaunch XML stays a launch-error (exit 1)."""
    record_project(project)
    if command == "build":
        monitor = MONITOR.replace('inv="p.inv"', 'inv="p.inv" launch="nowhere.launch"')
        (project / "m.xml").write_text(CONFIG.replace("</imROS>", monitor + "</imROS>"))
        args = ["build", "m.xml", "--backend", "ros1", "-o", "pkg", "--graph", "g.yaml"]
        graph = "version: 1\nnodes:\n  /n:\n    publishes: [/out]\n    subscribes: [/in]\n"
        (project / "g.yaml").write_text(graph)
    else:
        _no_master(monkeypatch)
        args = [*RECORD[:5], "nowhere.launch", *RECORD[6:8]]
        args = [arg.replace("{d}/", "") for arg in args]
    before = snapshot(project)
    monkeypatch.chdir(project)
    result = CliRunner().invoke(main, args)
    assert result.exit_code == USAGE, result.output
    assert "Traceback" not in result.output
    missing = "No such file or directory"
    said = {  # build reports it as a diagnostic; record refuses before the master and servers
        "build": f"nowhere.launch:1:1: error: cannot read the launch file: {missing}",
        "record": f"imrosc record: --launch nowhere.launch: cannot read it: {missing}",
    }
    assert said[command] in result.stderr, result.output
    assert snapshot(project) == before
    (project / "nowhere.launch").write_text("<launch><node")
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 1 and "[launch-error]" in result.stderr, result.output
