"""Diagnostics: what the compiler says about a file, and the three ways it prints them.

A diagnostic is ``file:line:col: severity: message [code]`` with 1-based line and column,
as mypy and gcc print them. Output is sorted and de-duplicated over all files of a run.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

from imrosc.codes import Severity, lookup


@dataclass(frozen=True, order=True)
class Diagnostic:
    """One finding at one place of one file."""

    path: str
    line: int
    column: int
    severity: Severity
    code: str
    message: str

    def as_text(self) -> str:
        """The compiler-style one-line form."""
        return (
            f"{self.path}:{self.line}:{self.column}: {self.severity.value}: "
            f"{self.message} [{self.code}]"
        )

    def as_json(self) -> dict[str, object]:
        """The JSON object form (stable keys)."""
        return {
            "path": self.path,
            "line": self.line,
            "column": self.column,
            "severity": self.severity.value,
            "code": self.code,
            "message": self.message,
        }


def make(path: str, line: int, column: int, code: str, message: str) -> Diagnostic:
    """Build a diagnostic with the registered default severity of ``code``."""
    return Diagnostic(path, max(line, 1), max(column, 1), lookup(code).severity, code, message)


def finalize(diagnostics: Iterable[Diagnostic], *, strict: bool = False) -> list[Diagnostic]:
    """Sort and de-duplicate; with ``strict`` every warning becomes an error."""
    found = set(diagnostics)
    if strict:
        found = {
            replace(d, severity=Severity.ERROR) if d.severity is Severity.WARNING else d
            for d in found
        }
    return sorted(found)


def has_errors(diagnostics: Iterable[Diagnostic]) -> bool:
    """Whether any diagnostic is an error."""
    return any(d.severity is Severity.ERROR for d in diagnostics)


def _summary(diagnostics: Sequence[Diagnostic], files: int) -> str:
    errors = sum(d.severity is Severity.ERROR for d in diagnostics)
    warnings = sum(d.severity is Severity.WARNING for d in diagnostics)
    noun = "file" if files == 1 else "files"
    if not errors and not warnings:
        return f"Success: no issues found in {files} {noun}"
    affected = len({d.path for d in diagnostics})
    return (
        f"Found {errors} error{'s' * (errors != 1)} and {warnings} "
        f"warning{'s' * (warnings != 1)} in {affected} file{'s' * (affected != 1)} "
        f"(checked {files} {noun})"
    )


def render_text(diagnostics: Sequence[Diagnostic], files: int) -> str:
    """One line per diagnostic and a closing summary line."""
    lines = [d.as_text() for d in diagnostics]
    lines.append(_summary(diagnostics, files))
    return "\n".join(lines) + "\n"


def render_json(diagnostics: Sequence[Diagnostic], files: int) -> str:
    """A JSON document: the diagnostics and their counts."""
    document = {
        "version": 1,
        "files": files,
        "errors": sum(d.severity is Severity.ERROR for d in diagnostics),
        "warnings": sum(d.severity is Severity.WARNING for d in diagnostics),
        "notes": sum(d.severity is Severity.NOTE for d in diagnostics),
        "diagnostics": [d.as_json() for d in diagnostics],
    }
    return json.dumps(document, indent=2) + "\n"


def _escape_data(text: str) -> str:
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def _escape_property(text: str) -> str:
    return _escape_data(text).replace(":", "%3A").replace(",", "%2C")


def render_github(diagnostics: Sequence[Diagnostic], files: int) -> str:
    """GitHub Actions workflow commands, one annotation per diagnostic."""
    lines = [
        f"::{d.severity.value} file={_escape_property(d.path)},line={d.line},col={d.column},"
        f"title={_escape_property('imrosc ' + d.code)}::{_escape_data(d.message)}"
        for d in diagnostics
    ]
    lines.append(_summary(diagnostics, files))
    return "\n".join(lines) + "\n"


RENDERERS = {"text": render_text, "json": render_json, "github": render_github}
