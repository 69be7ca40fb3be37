"""``imrosc check``: load, validate against the grammar, then check semantics, per file.

>>> import tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> (folder / "c.xml").write_text('<imROS project="p"><scope><publish id="A">/x</publish>'
...                                '</scope></imROS>')
70
>>> for d in check_file(folder / "c.xml", label="c.xml"): print(d.as_text())
c.xml:1:40: error: id 'A' of <publish> must be lowercase letters (e.g. 'a') [bad-id]
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from imrosc.diagnostics import Diagnostic, finalize, has_errors
from imrosc.schema.loader import MAX_CONFIG_BYTES, LoadedConfig, load_config, parse_config_bytes
from imrosc.schema.semantics import check_semantics
from imrosc.schema.validate import validate_structure


def check_loaded(config: LoadedConfig) -> list[Diagnostic]:
    """Structure and semantics of a configuration already loaded."""
    return validate_structure(config) + check_semantics(config)


def load_checked(config_path: Path) -> tuple[LoadedConfig | None, list[Diagnostic]]:
    """Read and check a configuration: the loaded tree (``None`` when it has errors) and the
    diagnostics so far (not yet finalized: the command adds its own). Commands that compile
    it go through :mod:`imrosc.frontend`, which lowers it and runs the passes."""
    config, problems = load_config(config_path)
    if config is not None:
        problems += check_loaded(config)
    if config is None or has_errors(problems):
        return None, problems
    return config, problems


def check_file(
    path: Path, *, label: str | None = None, max_bytes: int = MAX_CONFIG_BYTES
) -> list[Diagnostic]:
    """Every diagnostic of one configuration file, sorted."""
    config, problems = load_config(path, label=label, max_bytes=max_bytes)
    if config is not None:
        problems += check_loaded(config)
    return finalize(problems)


def check_bytes(data: bytes, label: str) -> list[Diagnostic]:
    """Every diagnostic of configuration bytes (``label`` names them in messages)."""
    config, problems = parse_config_bytes(data, label)
    if config is not None:
        problems += check_loaded(config)
    return finalize(problems)


def check_files(paths: Iterable[Path], *, strict: bool = False) -> list[Diagnostic]:
    """Every diagnostic of every file, sorted and de-duplicated across files."""
    found: list[Diagnostic] = []
    for path in paths:
        found += check_file(path)
    return finalize(found, strict=strict)
