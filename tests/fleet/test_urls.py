"""Bags by URL on the cluster: each worker downloads the bags it reads from a server on
loopback, and the invariants file and the replay report are those of one process."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from imrosc.cli import main
from tests.served import serve
from tests.translate import good_run

pytestmark = pytest.mark.slow

CONFIG = """<imROS project="p">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic></publish>
  </scope>
  <detect inv="p.inv" budget="0.2"><bag>{url}/bags/r*.bag</bag><bag>{url}/gone.bag</bag></detect>
</imROS>
"""


@pytest.fixture(scope="module")
def url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    folder = tmp_path_factory.mktemp("served")
    (folder / "bags").mkdir()
    for run in range(4):
        good_run(folder / "bags" / f"r{run}.bag", 10.0 * run, odd=run == 3)
    (folder / "bags" / "r9.bag").write_text("not a bag\n")
    with serve(folder) as served:
        yield served


def invoke(*arguments: str) -> Result:
    return CliRunner().invoke(main, [*arguments, "-q"])


def test_infer_and_replay_of_urls_on_the_cluster_are_those_of_one_process(
    url: str, address: str, tmp_path: Path
) -> None:
    config = tmp_path / "p.xml"
    config.write_text(CONFIG.format(url=url))
    alone = invoke("infer", str(config), "-j", "1", "-o", str(tmp_path / "one.inv"))
    fleet = invoke("infer", str(config), "--scheduler", address, "-o", str(tmp_path / "f.inv"))
    assert alone.exit_code == fleet.exit_code == 1, fleet.output  # the bags that are none
    assert (tmp_path / "f.inv").read_bytes() == (tmp_path / "one.inv").read_bytes()
    assert f"{url}/gone.bag:1:1: error: not found (HTTP 404) [bag-error]" in fleet.stderr
    assert f"{url}/bags/r9.bag:1:1: error: cannot open bag: " in fleet.stderr
    bags = [f"{url}/bags/r*.bag", f"{url}/bags/r3.bag"]
    one = invoke("replay", str(tmp_path / "one.inv"), *bags, "--json")
    many = invoke("replay", str(tmp_path / "one.inv"), *bags, "--json", "--scheduler", address)
    assert one.exit_code == many.exit_code
    assert many.stdout == one.stdout
    assert f'"bag": "{url}/bags/r3.bag"' in many.stdout
