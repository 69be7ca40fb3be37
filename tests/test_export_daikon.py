"""``imrosc export-daikon``: Daikon 5 declarations and one trace per bag.

Daikon itself (Java) is not installed here; the test checks the format Daikon's
decl-version 2.0 reader expects and that every translated sample is written exactly once.
"""

from __future__ import annotations

import re
from pathlib import Path

from click.testing import CliRunner

from imrosc.cli import main
from tests.test_infer_cli import good_run

CONFIG = """<imROS project="d">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic></publish>
  </scope>
  <detect inv="d.inv"><bag>bags</bag></detect>
</imROS>
"""


def test_decls_and_one_dtrace_per_bag(tmp_path: Path) -> None:
    (tmp_path / "bags").mkdir()
    good_run(tmp_path / "bags" / "r1.bag", 0.0)
    good_run(tmp_path / "bags" / "r2.bag", 50.0, odd=True)
    config = tmp_path / "d.xml"
    config.write_text(CONFIG)
    out = tmp_path / "daikon"
    result = CliRunner().invoke(main, ["export-daikon", str(config), "-o", str(out)])
    assert result.exit_code == 0, result.output
    decls = (out / "imrosc.decls").read_text()
    assert decls.startswith("decl-version 2.0\nvar-comparability none\n")
    assert "ppt a:::POINT\nppt-type point\n" in decls
    declared = re.findall(r"^variable (\S+)\n  var-kind variable\n  rep-type (\S+)\n", decls, re.M)
    assert ("time", "double") in declared and ("out.data", "double") in declared
    traces = sorted(out.glob("*.dtrace"))
    assert [t.name for t in traces] == ["000-r1.bag.dtrace", "001-r2.bag.dtrace"]
    for trace in traces:
        records = trace.read_text().strip().split("\n\n")
        assert len(records) == 40
        for record in records:
            lines = record.split("\n")
            assert lines[0] == "a:::POINT"
            names = lines[1::3]
            assert names == [name for name, _ in declared]
            assert all(flag in ("1", "2") for flag in lines[3::3])
    odd = (out / "001-r2.bag.dtrace").read_text()
    assert "out.data\nnonsensical\n2\n" in odd and "out.data\nInfinity\n1\n" in odd
