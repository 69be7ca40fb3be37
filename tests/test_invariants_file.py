"""Reading an invariants file (imrosc.invariants.load): a problem the shape check cannot see
but building the engine meets is located at the invariant that causes it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from imrosc.invariants import InvariantsFileError, load
from tests.bad_input.support import CONFIG
from tests.translate import good_run


@pytest.fixture(scope="module")
def document(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("inv")
    (folder / "p.xml").write_text(CONFIG)
    (folder / "bags" / "train").mkdir(parents=True)
    good_run(folder / "bags" / "train" / "r1.bag", 0.0)
    good_run(folder / "bags" / "train" / "r2.bag", 10.0)
    done = CliRunner().invoke(main, ["infer", str(folder / "p.xml"), "-j", "1", "-q"])
    assert done.exit_code == 0, done.output
    loaded: dict[str, Any] = json.loads((folder / "p.inv").read_text())
    return loaded


@pytest.mark.parametrize("which", ["first", "last"])
def test_a_parameter_the_engine_cannot_read_is_named_by_its_invariant(
    document: dict[str, Any], tmp_path: Path, which: str
) -> None:
    edited = json.loads(json.dumps(document))
    bounds = [i for i, inv in enumerate(edited["invariants"]) if inv["family"] == "bounds"]
    assert len(edited["invariants"]) > 4 and bounds
    index = bounds[0] if which == "first" else bounds[-1]
    edited["invariants"][index]["params"]["max"] = "high"
    path = tmp_path / "bad.inv"
    path.write_text(json.dumps(edited))
    with pytest.raises(InvariantsFileError) as raised:
        load(path)
    assert str(raised.value) == (
        f"{path}: malformed: $.invariants[{index}]: ValueError: "
        "could not convert string to float: 'high'"
    )


def test_the_file_as_written_loads(document: dict[str, Any], tmp_path: Path) -> None:
    path = tmp_path / "good.inv"
    path.write_text(json.dumps(document))
    assert load(path)["invariants"] == document["invariants"]
