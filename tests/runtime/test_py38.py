"""The runtime engine runs on ROS Noetic's Python 3.8 with numpy and the standard library."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import imrosc.runtime

RUNTIME = Path(imrosc.runtime.__file__).parent
MODULES = sorted(RUNTIME.glob("*.py"))
ALLOWED = frozenset(sys.stdlib_module_names) | {"numpy"}
OPTIONAL = {"compiled.py": {"numba"}}
"""Imports a module may try, falling back when they fail (``compiled.py``: numba)."""


def test_vermin_finds_nothing_newer_than_python_3_8() -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys, vermin; sys.argv[0] = 'vermin'; sys.exit(vermin.main())",
            "-t=3.8-",
            "--no-tips",
            "--violations",
            "--eval-annotations",
            str(RUNTIME),
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr


def imports(path: Path) -> list[tuple[int, str]]:
    """``(line, module)`` of every import of a module (relative ones as ``.name``)."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            found.append((node.lineno, "." * node.level + (node.module or "")))
    return found


def test_the_runtime_is_the_modules_we_walk() -> None:
    assert {p.stem for p in MODULES} >= {"engine", "checks", "windows", "temporal", "flatten"}


@pytest.mark.parametrize("path", MODULES, ids=lambda p: p.name)
def test_imports_only_numpy_the_standard_library_and_itself(path: Path) -> None:
    """Its own modules by relative import only: monitor packages carry a copy of the
    package under another name."""
    for line, module in imports(path):
        top = module.split(".")[0]
        inside = module.startswith(".") and module.count(".") == 1
        allowed = ALLOWED | OPTIONAL.get(path.name, set())
        assert inside or top in allowed, f"{path.name}:{line} imports {module}"


SCRIPT = textwrap.dedent(
    """
    import sys
    assert sys.version_info[:2] == (3, 8), sys.version
    from imrosc.runtime import Engine
    from imrosc.runtime.flatten import make_flattener

    variables = [{"name": "t.x", "path": "x", "type": "float", "derived": None},
                 {"name": "avg(t.r)", "path": "r", "type": "float", "derived": "avg"}]
    document = {
        "topics": {"/t": {"variables": variables}},
        "points": {"t": {"kind": "publish", "trigger": "/t", "variables": variables}},
        "invariants": [
            {"id": "i1", "family": "bounds", "kind": "upper", "point": "t",
             "variables": ["t.x"], "params": {"max": 1.0}, "text": "t.x <= 1"},
            {"id": "i2", "family": "variance", "kind": "range", "point": "t",
             "variables": ["t.x"], "params": {"min": 0.0, "max": 1.0, "window": 1.0},
             "text": "var"},
            {"id": "i3", "family": "frequency", "kind": "range", "point": "t",
             "variables": [], "params": {"min": 4.0, "max": 8.0, "window": 1.0},
             "text": "freq"},
        ],
    }
    class Message:
        def __init__(self, x, r):
            self.x, self.r = x, r
    engine = Engine(document)
    flatten = make_flattener(variables)
    found = []
    for k in range(12):
        found += engine.message("/t", k * 0.25, flatten(Message(0.5 if k < 11 else 3.0, (1, 2))))
    found += engine.advance(5.0)
    print(sorted((v.time, v.invariant) for v in found))
    """
)


def python38() -> str:
    found = shutil.which("python3.8")
    if found is None:
        pytest.skip("no python3.8 on PATH")
    probe = subprocess.run(
        [found, "-c", "import numpy"], capture_output=True, text=True, check=False, timeout=60
    )
    if probe.returncode != 0:
        pytest.skip("python3.8 cannot import numpy")
    return found


def test_a_tiny_engine_runs_under_python_3_8(tmp_path: Path) -> None:
    interpreter = python38()
    # only the runtime, as a monitor package carries it: nothing else of imrosc is there
    package = tmp_path / "imrosc"
    shutil.copytree(RUNTIME, package / "runtime", ignore=shutil.ignore_patterns("__pycache__"))
    (package / "__init__.py").write_text("")
    done = subprocess.run(
        [interpreter, "-I", "-c", f"import sys; sys.path.insert(0, {str(tmp_path)!r})\n{SCRIPT}"],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    # 4 Hz; x jumps to 3 at 2.75 s (bound and variance); silent after that: the timer
    assert done.stdout.strip() == "[(2.75, 'i1'), (2.75, 'i2'), (5.0, 'i3')]"
