"""What the tests of both monitor backends check alike."""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

from imrosc import __version__
from imrosc.outputs import GENERATED_MARK

ROOT = Path(__file__).resolve().parents[2]
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
