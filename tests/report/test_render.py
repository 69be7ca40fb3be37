"""``render``: what it refuses, and the packaging of its templates."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import pytest

from imrosc.report import DOCUMENTS, FORMATS, ReportError, render
from tests.report.documents import load

ROOT = Path(__file__).parent.parent.parent


def test_formats() -> None:
    assert FORMATS == ("text", "json", "html")
    assert DOCUMENTS == ("imrosc-replay", "imrosc-classify", "imrosc-stability")


def test_unknown_output_format() -> None:
    with pytest.raises(ReportError, match="unknown report format 'pdf'"):
        render(load("replay"), "pdf")  # type: ignore[arg-type]


@pytest.mark.parametrize("fmt", ["text", "html"])
def test_unknown_document_format(fmt: Any) -> None:
    with pytest.raises(ReportError, match="unknown document format 'imrosc-other'"):
        render({"format": "imrosc-other", "version": 1}, fmt)
    with pytest.raises(ReportError, match="unknown document format None"):
        render({}, fmt)


@pytest.mark.parametrize("fmt", ["text", "html"])
def test_unsupported_version(fmt: Any) -> None:
    document = load("stability")
    document["version"] = 2
    with pytest.raises(ReportError, match="version 2 is not supported"):
        render(document, fmt)


@pytest.mark.parametrize("fmt", ["text", "html"])
def test_missing_field(fmt: Any) -> None:
    document = load("replay")
    del document["runs"][0]["bag"]
    with pytest.raises(ReportError, match="imrosc-replay document lacks a field: 'bag'"):
        render(document, fmt)


def test_json_refuses_non_finite_numbers() -> None:
    document = load("replay")
    document["runs"][0]["episodes"][0]["observed"] = float("nan")
    with pytest.raises(ReportError, match="not strict JSON"):
        render(document, "json")
    # text and HTML spell it
    assert "observed nan, expected inside the 4-vertex polygon" in render(document, "text")


def test_templates_are_package_data() -> None:
    templates = resources.files("imrosc.report") / "templates"
    names = {t.name for t in templates.iterdir()}
    assert {"base.html.j2", "charts.html.j2", "replay.html.j2"} <= names
    assert {"classify.html.j2", "stability.html.j2"} <= names
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert '"imrosc.report" = ["templates/*.j2"]' in pyproject
