"""The onboard package runs on ROS Noetic's Python 3.8 with numpy, the standard library and
the runtime engine it is copied beside."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import imrosc.onboard

ONBOARD = Path(imrosc.onboard.__file__).parent
ALLOWED = frozenset(sys.stdlib_module_names) | {"numpy", "__future__"}


def test_vermin_finds_nothing_newer_than_python_3_8() -> None:
    pytest.importorskip("vermin")
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys, vermin; sys.argv[0] = 'vermin'; sys.exit(vermin.main())",
            *("-t=3.8-", "--no-tips", "--violations", "--eval-annotations", str(ONBOARD)),
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr


@pytest.mark.parametrize("path", sorted(ONBOARD.glob("*.py")), ids=lambda p: p.name)
def test_it_imports_the_standard_library_numpy_and_the_runtime_only(path: Path) -> None:
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level == 1:  # a sibling onboard module
                continue
            if node.level == 2:  # ..runtime, copied beside onboard
                assert (node.module or "").split(".")[0] == "runtime", (path.name, node.lineno)
                continue
            names = [node.module or ""]
        else:
            continue
        for name in names:
            assert name.split(".")[0] in ALLOWED, (path.name, node.lineno, name)
