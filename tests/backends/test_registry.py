"""Backends are found by entry point (group ``imrosc.backends``): a package adds one with its
own module and one entry point, no change to imrosc."""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

import pytest

from imrosc.backends import registry
from imrosc.build import build

CONFIG = """<imROS project="toyproj">
  <scope>
    <publish id="a">/out</publish>
  </scope>
</imROS>
"""


def with_entry_points(monkeypatch: pytest.MonkeyPatch, **modules: str) -> None:
    points = [metadata.EntryPoint(n, m, registry.GROUP) for n, m in modules.items()]
    monkeypatch.setattr(
        metadata, "entry_points", lambda group: [p for p in points if p.group == group]
    )


def test_imroscs_own_backends_are_entry_points() -> None:
    found = {p.name: p.value for p in metadata.entry_points(group=registry.GROUP)}
    assert found == {name: f"imrosc.backends.{name}" for name in ("plan", "ros1", "ros2")}
    assert registry.names() == ["plan", "ros1", "ros2"]
    assert {n for n in registry.available() if registry.is_monitor(n)} == {"ros1", "ros2"}


def test_a_third_party_backend_builds(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    with_entry_points(monkeypatch, toy="tests.backends.third_party.toy")
    monkeypatch.setattr(registry, "BACKENDS", dict(registry.BACKENDS))
    assert "toy" in registry.names()
    (tmp_path / "toy.xml").write_text(CONFIG)
    result = build(tmp_path / "toy.xml", "toy")
    assert result.ok, [d.as_text() for d in result.diagnostics]
    text = result.files["points.txt"].decode()
    assert "(backend toy)" in text and text.endswith("\na\n")
    assert not registry.is_monitor("toy")


def test_a_backend_that_registers_nothing_is_an_error(monkeypatch: pytest.MonkeyPatch) -> None:
    with_entry_points(monkeypatch, silent="tests.backends.third_party.silent")
    with pytest.raises(registry.BackendError, match="registers no renderer named silent"):
        registry.available()
    with_entry_points(monkeypatch, gone="tests.backends.third_party.missing")
    with pytest.raises(registry.BackendError, match="cannot import"):
        registry.available()
