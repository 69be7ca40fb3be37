"""Bags on object storage (``s3://``): an S3 server on loopback (moto's, the S3 API as AWS
serves it) holds the bags; ``infer`` and ``replay`` read them through s3fs, as they would
from AWS or any S3-compatible store, and give what the same bags on disk give."""

from __future__ import annotations

import socket
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from imrosc.cli import main
from tests.translate import good_run

boto3 = pytest.importorskip("boto3")
pytest.importorskip("s3fs")
server = pytest.importorskip("moto.server")

CONFIG = """<imROS project="p">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic></publish>
  </scope>
  <detect inv="p.inv" budget="0.2">{bags}</detect>
</imROS>
"""
BUCKET = "fleet"


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    base = tmp_path_factory.mktemp("s3")
    (base / "bags").mkdir()
    for k in range(3):
        good_run(base / "bags" / f"r{k}.bag", 10.0 * k)
    return base


@pytest.fixture(scope="module")
def endpoint(folder: Path) -> Iterator[str]:
    """An S3 server on 127.0.0.1 whose bucket holds the folder's bags under ``runs/``."""
    port = _free_port()
    served = server.ThreadedMotoServer(ip_address="127.0.0.1", port=port, verbose=False)
    served.start()
    url = f"http://127.0.0.1:{port}"
    patch = pytest.MonkeyPatch()
    for name, value in {
        "AWS_ACCESS_KEY_ID": "imrosc",
        "AWS_SECRET_ACCESS_KEY": "imrosc",
        "AWS_DEFAULT_REGION": "us-east-1",
        "AWS_ENDPOINT_URL_S3": url,  # botocore's S3 endpoint (so s3fs's): the server above
    }.items():
        patch.setenv(name, value)
    try:
        client = boto3.client("s3", endpoint_url=url)
        client.create_bucket(Bucket=BUCKET)
        for bag in sorted((folder / "bags").glob("*.bag")):
            client.upload_file(str(bag), BUCKET, f"runs/{bag.name}")
        yield url
    finally:
        patch.undo()
        served.stop()


def invoke(*arguments: str) -> Result:
    return CliRunner().invoke(main, [*arguments, "-q"])


def configured(folder: Path, name: str, *bags: str) -> Path:
    config = folder / name
    config.write_text(CONFIG.format(bags="".join(f"<bag>{bag}</bag>" for bag in bags)))
    return config


def test_infer_and_replay_of_s3_bags_give_what_the_bags_on_disk_give(
    folder: Path, endpoint: str
) -> None:
    local = configured(folder, "local.xml", "bags/r0.bag", "bags/r1.bag")
    remote = configured(folder, "remote.xml", f"s3://{BUCKET}/runs/r[01].bag")
    done = invoke("infer", str(local), "-j", "1", "-o", str(folder / "local.inv"))
    assert done.exit_code == 0, done.output
    done = invoke("infer", str(remote), "-j", "1", "-o", str(folder / "remote.inv"))
    assert done.exit_code == 0, done.output
    assert "from 2 bags" in done.output
    expected = (folder / "local.inv").read_text().replace("local.xml", "remote.xml")
    got = (folder / "remote.inv").read_text().replace(f"s3://{BUCKET}/runs/", f"{folder}/bags/")
    assert got == expected
    inv = str(folder / "local.inv")
    on_disk = invoke("replay", inv, str(folder / "bags" / "r2.bag"), "--json")
    stored = invoke("replay", inv, f"s3://{BUCKET}/runs/r2.bag", "--json")
    assert stored.exit_code == on_disk.exit_code
    assert '"error": null' in stored.stdout
    assert stored.stdout.replace(f"s3://{BUCKET}/runs/", f"{folder}/bags/") == on_disk.stdout


def test_a_missing_object_is_one_line_naming_it(folder: Path, endpoint: str) -> None:
    missing = f"s3://{BUCKET}/runs/absent.bag"
    done = invoke("info", missing)
    assert done.exit_code == 2 and "Traceback" not in done.output
    lines = [line for line in done.output.splitlines() if "absent.bag" in line]
    assert len(lines) == 1, done.output
