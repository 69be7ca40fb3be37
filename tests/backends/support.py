"""What the tests of both monitor backends check alike."""

from __future__ import annotations

import itertools
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

from imrosc import __version__
from imrosc.backends.vendor import NOT_COPIED
from imrosc.outputs import GENERATED_MARK

ROOT = Path(__file__).resolve().parents[2]
HOSTILE = "'); import os; os.system('zqvalue') #\"\"\" \\\n--> ]]> {{ }}"
"""A value that breaks out of every kind of quoting (Python, XML, Jinja) unless it is quoted."""
_COPY = re.compile(r"\):acopyof(imrosc/[a-z0-9_/]+\.py);donotedit")


def assert_every_file_names_its_source(
    package: Mapping[str, bytes], config: Path, backend: str
) -> None:
    """Every file of a generated ``package`` names the generator, its version and the
    backend; a copy of one of imrosc's modules names that module, every other file the
    configuration ``config`` (comments may wrap a long path: compared without spaces)."""
    source = "".join(str(config).split())
    copies = 0
    for name, content in package.items():
        head = content[:4096].decode("utf-8")
        assert GENERATED_MARK in head, name
        assert __version__ in head and f"backend {backend}" in head, name
        flat = "".join(head.replace("#", "").split())
        copied = _COPY.search(flat)
        if copied is not None:
            copies += 1
            assert name.endswith("/" + copied.group(1).rsplit("/", 1)[1]), name
            assert (ROOT / copied.group(1)).is_file() and source not in flat, name
        else:
            assert source in flat, name
    assert copies > 10


def vendored_sources(root: str, packages: Sequence[str]) -> dict[str, Path]:
    """The copies of imrosc's modules that a package's Python package at ``root`` carries,
    in imrosc's own layout under ``root/imrosc/``, each to the module it copies:
    ``imrosc/__init__.py`` and every module of ``packages`` (``runtime``, ``onboard``, ...)
    but those only ``imrosc record`` runs (:data:`imrosc.backends.vendor.NOT_COPIED`)."""
    found = {f"{root}/imrosc/__init__.py": ROOT / "imrosc" / "__init__.py"}
    for name in packages:
        for path in sorted((ROOT / "imrosc" / name).glob("*.py")):
            if f"{name}/{path.name}" not in NOT_COPIED:
                found[f"{root}/imrosc/{name}/{path.name}"] = path
    return found


def without_banner(text: str) -> str:
    """A copied module without its banner (the first line and its ``#   `` continuations)."""
    lines = text.splitlines(keepends=True)
    banner = 1 + sum(1 for _ in itertools.takewhile(lambda x: x.startswith("#   "), lines[1:]))
    return "".join(lines[banner:])


def assert_carried_unchanged(package: Mapping[str, bytes], sources: Mapping[str, Path]) -> None:
    """Every copy of ``sources`` (path in ``package`` -> module) is a banner and the module."""
    for name, path in sources.items():
        copy = package[name].decode()
        assert copy.startswith("# " + GENERATED_MARK), name
        assert without_banner(copy) == path.read_text(encoding="utf-8"), name
