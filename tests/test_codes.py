"""The code registry and the docs page stay in step; codes are stable kebab-case names."""

from __future__ import annotations

import re
from pathlib import Path

from imrosc.codes import BY_NAME, CODES

DOCS = Path(__file__).parent.parent / "docs" / "diagnostics.md"


def test_codes_are_unique_kebab_case() -> None:
    names = [c.name for c in CODES]
    assert len(names) == len(set(names))
    assert all(re.fullmatch(r"[a-z0-9]+(-[a-z0-9]+)*", n) for n in names)


def test_docs_page_lists_every_code_with_its_severity() -> None:
    text = DOCS.read_text(encoding="utf-8")
    rows = dict(
        re.findall(r"^\| \[`([a-z0-9-]+)`\]\(#[a-z0-9-]+\) \| (error|warning|note) \|", text, re.M)
    )
    sections = re.findall(r"^## ([a-z0-9-]+)$", text, re.M)
    assert set(rows) == set(BY_NAME), "docs table and registry differ"
    assert sections == [c.name for c in CODES], "docs sections and registry differ"
    assert all(BY_NAME[name].severity.value == severity for name, severity in rows.items())
