"""A package's nodes find its generated files beside their copy of imrosc
(``imrosc/onboard/files.py``)."""

from __future__ import annotations

import json
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


def test_an_invariants_file_the_engine_cannot_read_is_one_line_naming_it(tmp_path: Path) -> None:
    """A package's ``config/invariants.json`` edited by hand, or another ``~invariants``:
    the node says which file and where, as ``imrosc`` does (``imrosc/invariants.py``)."""
    bad = tmp_path / "bad.json"
    with pytest.raises(files.InvariantsError, match=r"bad\.json: cannot read: No such file"):
        files.load_invariants(str(bad))
    bad.write_text('{"format": "imrosc-invariants",\n "topics": {}')
    with pytest.raises(files.InvariantsError, match=r"bad\.json:2:14: not JSON: Expecting"):
        files.load_invariants(str(bad))
    bad.write_bytes(b'{"format": "\xff"}')
    with pytest.raises(files.InvariantsError, match=r"bad\.json: not UTF-8 text"):
        files.load_invariants(str(bad))
    point = {"kind": "publish", "variables": [{"name": "x.v", "type": "float"}]}
    invariant = {
        "id": "i1",
        "family": "bounds",
        "kind": "upper",
        "point": "x",
        "variables": ["x.v"],
        "params": {"max": 1.0},
        "text": "x.v <= 1",
    }
    good = {"format": "imrosc-invariants", "topics": {}, "points": {"x": point}}
    cases = {
        "$.invariants[0]: missing 'point'": {k: v for k, v in invariant.items() if k != "point"},
        "$.invariants[0].point: no point 'y' in 'points'": {**invariant, "point": "y"},
        "$.invariants[0].params: not an object": {**invariant, "params": []},
    }
    for problem, edited in cases.items():
        bad.write_text(json.dumps({**good, "invariants": [edited]}))
        with pytest.raises(files.InvariantsError) as raised:
            files.load_invariants(str(bad))
        assert str(raised.value) == f"{bad}: malformed: {problem}"
    bad.write_text(json.dumps({**good, "points": {"x": {"kind": "publish"}}, "invariants": []}))
    with pytest.raises(files.InvariantsError, match=r"\$\.points\.x: missing 'variables'"):
        files.load_invariants(str(bad))
    bad.write_text(json.dumps({**good, "invariants": [invariant]}))
    assert files.load_invariants(str(bad))["invariants"] == [invariant]
