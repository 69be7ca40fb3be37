"""A package's nodes find its generated files beside their copy of imrosc
(``imrosc/onboard/files.py``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from imrosc.onboard import files


def test_the_spec_and_invariants_load_or_say_why(tmp_path: Path) -> None:
    (tmp_path / "spec.json").write_text('{"package": "p"}')
    assert files.load_spec(str(tmp_path)) == {"package": "p"}
    (tmp_path / "recorder.json").write_text('{"services": []}')
    assert files.load_spec(str(tmp_path), "recorder.json") == {"services": []}
    bad = tmp_path / "bad.inv"
    bad.write_text('{"format": "other"}')
    with pytest.raises(ValueError, match="not an imrosc invariants file"):
        files.load_invariants(str(bad))
    bad.write_text('{"format": "imrosc-invariants", "topics": {}}')
    with pytest.raises(ValueError, match="missing 'points'"):
        files.load_invariants(str(bad))


def test_the_package_folder_holds_the_copy_of_imrosc() -> None:
    # in imrosc's tree the "package" is the folder holding imrosc/, as <pkg>/ holds <pkg>/imrosc/
    assert Path(files.package_folder()) == Path(files.__file__).resolve().parents[2]
