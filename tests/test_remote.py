"""Bags by URL and globs (imrosc.remote): bags served over HTTP and by S3 and Google Cloud
Storage servers on loopback read by ``infer`` and ``replay`` as the same bags on disk are,
globs of URLs and of paths, and the local copies a reading process makes deleted after."""

from __future__ import annotations

import os
import pickle
import socket
import tempfile
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from imrosc.bags import discover_bags, open_bag
from imrosc.cli import main
from imrosc.remote import GCS_EMULATOR, GCSFS_CONTROL_PLANE, BagUrl, Scratch, bag_path
from imrosc.sim import write_run
from tests.served import serve
from tests.translate import good_run

CONFIG = """<imROS project="p">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic></publish>
  </scope>
  <detect inv="p.inv" budget="0.2">{bags}</detect>
</imROS>
"""


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three training runs, a file that is no bag, and two ROS 2 bags (folders)."""
    base = tmp_path_factory.mktemp("remote")
    (base / "bags").mkdir()
    good_run(base / "bags" / "r0.bag", 0.0)
    good_run(base / "bags" / "r1.bag", 10.0)
    good_run(base / "bags" / "r2.bag", 20.0)
    (base / "bags" / "notes.txt").write_text("not a bag\n")
    for fmt in ("mcap", "sqlite3"):
        write_run(base / "ros2" / fmt, seed=3, fmt=fmt, duration=1.0)
    return base


@pytest.fixture(scope="module")
def url(folder: Path) -> Iterator[str]:
    with serve(folder) as served:
        yield served


def invoke(*arguments: str) -> Result:
    return CliRunner().invoke(main, [*arguments, "-q"])


def configured(folder: Path, name: str, *bags: str) -> Path:
    config = folder / name
    config.write_text(CONFIG.format(bags="".join(f"<bag>{bag}</bag>" for bag in bags)))
    return config


def test_a_bag_url_is_a_path_that_prints_and_pickles_as_its_url() -> None:
    bag = bag_path("https://host:8080/fleet/r1.bag?v=2")
    assert isinstance(bag, BagUrl)
    assert (str(bag), bag.name, bag.suffix) == (
        "https://host:8080/fleet/r1.bag?v=2",
        "r1.bag",
        ".bag",
    )
    assert bag.absolute() is bag and bag.resolve() is bag
    assert pickle.loads(pickle.dumps(bag)) == bag
    assert str(bag.parent / "r2.bag") == "https://host:8080/fleet/r2.bag"
    assert bag_path("file:///data/r1.bag") == Path("/data/r1.bag")
    assert bag_path("runs/r1.bag", Path("/data")) == Path("/data/runs/r1.bag")
    mixed: list[Path] = [bag, Path("/a")]
    assert sorted(mixed) == [Path("/a"), bag]


def test_infer_from_urls_writes_the_invariants_of_the_same_bags_on_disk(
    folder: Path, url: str, tmp_path: Path
) -> None:
    local = configured(folder, "local.xml", "bags/r0.bag", "bags/r1.bag", "bags/r2.bag")
    remote = configured(folder, "remote.xml", f"{url}/bags/r0.bag", f"{url}/bags/r[12].bag")
    assert invoke("infer", str(local), "-j", "1", "-o", str(tmp_path / "local.inv")).exit_code == 0
    done = invoke("infer", str(remote), "-j", "2", "-o", str(tmp_path / "remote.inv"))
    assert done.exit_code == 0, done.output
    assert "from 3 bags" in done.output
    expected = (tmp_path / "local.inv").read_text().replace("local.xml", "remote.xml")
    got = (tmp_path / "remote.inv").read_text().replace(f"{url}/", f"{folder}/")
    assert got == expected


def test_replay_of_urls_reports_what_the_same_bags_on_disk_give(
    folder: Path, url: str, tmp_path: Path
) -> None:
    config = configured(folder, "train.xml", "bags/r0.bag", "bags/r1.bag")
    inv = tmp_path / "p.inv"
    assert invoke("infer", str(config), "-j", "1", "-o", str(inv)).exit_code == 0
    local = invoke("replay", str(inv), str(folder / "bags" / "r2.bag"), "--json")
    remote = invoke("replay", str(inv), f"{url}/bags/r2.bag", "--json")
    assert local.exit_code == remote.exit_code
    assert '"error": null' in remote.stdout
    assert remote.stdout.replace(f"{url}/", f"{folder}/") == local.stdout


def test_globs_name_the_bags_they_match_for_paths_and_urls(folder: Path, url: str) -> None:
    bags = folder / "bags"
    assert discover_bags(bags / "r[01].bag") == ([bags / "r0.bag", bags / "r1.bag"], [])
    assert discover_bags(BagUrl(f"{url}/bags/r*.bag")) == (
        [BagUrl(f"{url}/bags/r{run}.bag") for run in range(3)],
        [],
    )
    assert discover_bags(BagUrl(f"{url}/bags/")) == (
        [BagUrl(f"{url}/bags/r{run}.bag") for run in range(3)],
        [],
    )
    signed = BagUrl(f"{url}/bags/r1.bag?X-Amz-Signature=ab&X-Amz-Expires=60")
    assert discover_bags(signed) == ([signed], [])
    with open_bag(signed) as reader:
        assert reader.message_count == 80
    for pattern in (bags / "z*.bag", BagUrl(f"{url}/bags/z*.bag")):
        found, problems = discover_bags(pattern)
        assert found == []
        assert [(p.path, p.message) for p in problems] == [
            (str(pattern), "no bag matches the pattern")
        ]


def test_a_glob_on_the_command_line_reads_the_bags_it_matches(folder: Path, tmp_path: Path) -> None:
    config = configured(folder, "globbed.xml", "bags/r*.bag")
    done = invoke("infer", str(config), "-j", "1", "-o", str(tmp_path / "a.inv"))
    assert done.exit_code == 0, done.output
    assert "from 3 bags" in done.output
    again = invoke(
        "infer",
        str(config),
        "-j",
        "1",
        "-o",
        str(tmp_path / "b.inv"),
        "--bags",
        str(folder / "bags" / "r*.bag"),
    )
    assert again.exit_code == 0, again.output
    assert (tmp_path / "a.inv").read_bytes() == (tmp_path / "b.inv").read_bytes()


def test_a_local_copy_is_deleted_once_read_and_kept_for_the_next_read_in_the_main_process(
    url: str,
) -> None:
    before = set(Path(tempfile.gettempdir()).glob("imrosc-bag-*"))
    bag = BagUrl(f"{url}/bags/r0.bag")
    once = Scratch(0)
    with once.local(bag) as copy:
        assert copy.is_file() and copy.name == "r0.bag"
    assert not copy.exists()
    kept = Scratch(1 << 30)
    with kept.local(bag) as first, kept.local(bag) as second:
        assert first == second
    assert first.exists()
    kept.clear()
    assert not first.exists()
    assert set(Path(tempfile.gettempdir()).glob("imrosc-bag-*")) == before


def test_open_bag_reads_a_url_as_the_file_it_names(folder: Path, url: str) -> None:
    with (
        open_bag(BagUrl(f"{url}/bags/r1.bag")) as remote,
        open_bag(folder / "bags" / "r1.bag") as local,
    ):
        assert remote.message_count == local.message_count == 80
        assert [c.topic for c in remote.connections] == [c.topic for c in local.connections]


@pytest.mark.parametrize("fmt", ["mcap", "sqlite3"])
def test_a_ros2_bag_folder_by_url_is_fetched_with_the_storage_files_it_lists(
    folder: Path, url: str, fmt: str
) -> None:
    for named in (f"{url}/ros2/{fmt}", f"{url}/ros2/{fmt}/metadata.yaml"):
        assert discover_bags(BagUrl(named)) == ([BagUrl(f"{url}/ros2/{fmt}")], [])
    with (
        open_bag(BagUrl(f"{url}/ros2/{fmt}")) as remote,
        open_bag(folder / "ros2" / fmt) as local,
    ):
        assert remote.message_count == local.message_count > 0


def test_an_object_stores_folders_and_globs_name_its_bags(folder: Path, tmp_path: Path) -> None:
    """fsspec's memory file system lists folders and keys as object stores (s3://, gs://)
    do: paths without the protocol, no folder objects."""
    import fsspec

    store = fsspec.filesystem("memory")
    root = f"memory://{tmp_path.name}"
    for run in range(3):
        store.pipe_file(f"{root}/uav/r{run}.bag", (folder / "bags" / f"r{run}.bag").read_bytes())
    for part in ("metadata.yaml", "mcap.mcap"):
        store.pipe_file(f"{root}/uav/ros2/{part}", (folder / "ros2" / "mcap" / part).read_bytes())
    every = [BagUrl(f"{root}/uav/{name}") for name in ("r0.bag", "r1.bag", "r2.bag", "ros2")]
    assert discover_bags(BagUrl(f"{root}/uav")) == (every, [])
    assert discover_bags(BagUrl(f"{root}/uav/r*.bag")) == (every[:3], [])
    found, problems = discover_bags(BagUrl(f"{root}/elsewhere"))
    assert found == [] and [p.message for p in problems] == ["not found"]
    config = configured(folder, "store.xml", "bags/r0.bag")
    infer = ["infer", str(config), "-j", "1", "-o"]
    local = invoke(*infer, str(tmp_path / "local.inv"), "--bags", str(folder / "bags" / "r*.bag"))
    assert local.exit_code == 0, local.output
    stored = invoke(*infer, str(tmp_path / "stored.inv"), "--bags", f"{root}/uav/r*.bag")
    assert stored.exit_code == 0, stored.output
    got = (tmp_path / "stored.inv").read_text().replace(f"{root}/uav/", f"{folder}/bags/")
    assert got == (tmp_path / "local.inv").read_text()


# --- object stores: s3:// and gs:// ------------------------------------------------------

BUCKET = "fleet"


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@contextmanager
def _s3(bags: list[Path]) -> Iterator[None]:
    """An S3 server on 127.0.0.1 (moto's: the S3 API as AWS serves it) whose bucket holds
    ``bags`` under ``runs/``; s3fs reaches it through botocore's endpoint variable."""
    boto3 = pytest.importorskip("boto3")
    pytest.importorskip("s3fs")
    server = pytest.importorskip("moto.server")
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
        for bag in bags:
            client.upload_file(str(bag), BUCKET, f"runs/{bag.name}")
        yield
    finally:
        patch.undo()
        served.stop()


@contextmanager
def _gcs(bags: list[Path]) -> Iterator[None]:
    """A Google Cloud Storage server on 127.0.0.1 (gcp-storage-emulator: the JSON API as
    Google serves it) whose bucket holds ``bags`` under ``runs/``; gcsfs reaches it through
    its endpoint variable, and imrosc turns gcsfs's gRPC bucket lookup off for it."""
    pytest.importorskip("gcsfs")
    server = pytest.importorskip("gcp_storage_emulator.server")
    port = _free_port()
    served = server.create_server("127.0.0.1", port, in_memory=True, default_bucket=BUCKET)
    served.start()
    url = f"http://127.0.0.1:{port}"
    patch = pytest.MonkeyPatch()
    patch.setenv(GCS_EMULATOR, url)
    patch.delenv(GCSFS_CONTROL_PLANE, raising=False)  # imrosc sets it: undone after
    try:
        for bag in bags:
            upload = urllib.request.Request(
                f"{url}/upload/storage/v1/b/{BUCKET}/o?uploadType=media&name=runs/{bag.name}",
                data=bag.read_bytes(),
                method="POST",
            )
            urllib.request.urlopen(upload, timeout=30).close()
        yield
    finally:
        patch.undo()
        served.stop()


STORES = {"s3": _s3, "gs": _gcs}
"""Per protocol, a server on loopback holding the bags, and what points its client at it."""


@pytest.fixture(scope="module", params=sorted(STORES))
def store(request: pytest.FixtureRequest, folder: Path) -> Iterator[str]:
    """The URL of the folder's bags (``runs/``) in an object store on loopback."""
    with STORES[request.param](sorted((folder / "bags").glob("r*.bag"))):
        yield f"{request.param}://{BUCKET}/runs/"


def test_infer_and_replay_of_stored_bags_give_what_the_bags_on_disk_give(
    folder: Path, store: str, tmp_path: Path
) -> None:
    local = configured(folder, "store_local.xml", "bags/r0.bag", "bags/r1.bag")
    remote = configured(folder, "store_remote.xml", f"{store}r[01].bag")
    done = invoke("infer", str(local), "-j", "1", "-o", str(tmp_path / "local.inv"))
    assert done.exit_code == 0, done.output
    done = invoke("infer", str(remote), "-j", "1", "-o", str(tmp_path / "remote.inv"))
    assert done.exit_code == 0, done.output
    assert "from 2 bags" in done.output
    expected = (tmp_path / "local.inv").read_text().replace("store_local.xml", "store_remote.xml")
    got = (tmp_path / "remote.inv").read_text().replace(store, f"{folder}/bags/")
    assert got == expected
    inv = str(tmp_path / "local.inv")
    on_disk = invoke("replay", inv, str(folder / "bags" / "r2.bag"), "--json")
    stored = invoke("replay", inv, f"{store}r2.bag", "--json")
    assert stored.exit_code == on_disk.exit_code
    assert '"error": null' in stored.stdout
    assert stored.stdout.replace(store, f"{folder}/bags/") == on_disk.stdout
    if store.startswith("gs://"):  # no minute-long gRPC lookup of the bucket's kind
        assert os.environ.get(GCSFS_CONTROL_PLANE) == "false"


def test_a_missing_object_is_one_line_naming_it(store: str) -> None:
    done = invoke("info", f"{store}absent.bag")
    assert done.exit_code == 2 and "Traceback" not in done.output
    lines = [line for line in done.output.splitlines() if "absent.bag" in line]
    assert len(lines) == 1, done.output
