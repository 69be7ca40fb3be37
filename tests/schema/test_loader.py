"""Safe loading: hostile documents give a diagnostic fast and touch nothing else.

"Touch nothing else" is tested with traps that cannot be missed: an XXE entity points at a
FIFO that no one writes (opening it for reading would block the check forever), and an
external DTD and an external entity point at an HTTP server on loopback that records every
request. Each check runs in a subprocess with a deadline.
"""

from __future__ import annotations

import http.server
import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import ClassVar

import pytest

from imrosc.check import check_file
from imrosc.schema.loader import MAX_CONFIG_BYTES, parse_config_bytes

BODY = '<imROS project="p"><scope><publish id="a">/a/x</publish></scope></imROS>\n'


def run_check(path: Path) -> tuple[float, subprocess.CompletedProcess[str]]:
    """``imrosc check`` in a fresh interpreter; returns (seconds, result)."""
    started = time.monotonic()
    result = subprocess.run(
        [sys.executable, "-m", "imrosc", "check", str(path)],
        capture_output=True,
        text=True,
        timeout=20,
        check=False,
    )
    return time.monotonic() - started, result


class _Recorder(http.server.BaseHTTPRequestHandler):
    requests: ClassVar[list[str]] = []

    def do_GET(self) -> None:
        _Recorder.requests.append(self.path)
        self.send_response(200)
        self.end_headers()
        self.wfile.write(b'<!ENTITY leak "LEAKED">')

    def log_message(self, format: str, *args: object) -> None:
        pass


@pytest.fixture
def http_trap() -> Iterator[tuple[str, list[str]]]:
    _Recorder.requests = []
    server = http.server.HTTPServer(("127.0.0.1", 0), _Recorder)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_port}", _Recorder.requests
    finally:
        server.shutdown()
        server.server_close()


def test_xxe_file_read_is_refused_without_opening_the_file(tmp_path: Path) -> None:
    fifo = tmp_path / "secret"
    os.mkfifo(fifo)
    config = tmp_path / "xxe.xml"
    config.write_text(
        f'<?xml version="1.0"?>\n<!DOCTYPE imROS [<!ENTITY xxe SYSTEM "file://{fifo}">]>\n'
        '<imROS project="p"><scope><publish id="a">&xxe;</publish></scope></imROS>\n'
    )
    seconds, result = run_check(config)
    assert result.returncode == 1
    assert f"{config}:2:1: error:" in result.stdout
    assert "[dtd-forbidden]" in result.stdout
    assert seconds < 10  # opening the FIFO would have blocked until the 20 s timeout


def test_external_dtd_and_entities_make_no_network_access(
    tmp_path: Path, http_trap: tuple[str, list[str]]
) -> None:
    url, requests = http_trap
    config = tmp_path / "dtd.xml"
    config.write_text(
        f'<!DOCTYPE imROS SYSTEM "{url}/imros.dtd" [<!ENTITY % p SYSTEM "{url}/p"> %p;]>\n'
        f'<imROS project="p"><scope><publish id="a">&leak;</publish></scope></imROS>\n'
    )
    _, result = run_check(config)
    assert "[dtd-forbidden]" in result.stdout
    assert "LEAKED" not in result.stdout + result.stderr
    assert requests == []


def test_even_the_parser_alone_resolves_nothing(http_trap: tuple[str, list[str]]) -> None:
    """The lxml parser settings are a second wall behind the DOCTYPE refusal."""
    from lxml import etree

    from imrosc.schema.loader import _parser

    url, requests = http_trap
    document = (
        f'<!DOCTYPE imROS SYSTEM "{url}/x.dtd" [<!ENTITY e SYSTEM "{url}/e">]><imROS>&e;</imROS>'
    ).encode()
    try:
        root = etree.fromstring(document, _parser())
    except etree.XMLSyntaxError as error:
        assert "network" in str(error)  # libxml2 refuses the fetch itself
    else:
        assert "LEAKED" not in etree.tostring(root).decode()
    assert requests == []


def test_billion_laughs_is_refused_fast(tmp_path: Path) -> None:
    entities = ['<!ENTITY lol0 "lol">'] + [
        f'<!ENTITY lol{i} "{("&lol" + str(i - 1) + ";") * 10}">' for i in range(1, 10)
    ]
    config = tmp_path / "lol.xml"
    config.write_text(
        "<?xml version='1.0'?>\n<!DOCTYPE imROS [\n" + "\n".join(entities) + "\n]>\n"
        '<imROS project="p"><scope><publish id="a">&lol9;</publish></scope></imROS>\n'
    )
    started = time.monotonic()
    found = check_file(config)
    assert time.monotonic() - started < 1.0
    assert [(d.line, d.code) for d in found] == [(2, "dtd-forbidden")]


def test_fifty_megabyte_file_is_refused_unread(tmp_path: Path) -> None:
    config = tmp_path / "huge.xml"
    with open(config, "w", encoding="utf-8") as stream:
        stream.write('<imROS project="p"><scope>')
        chunk = "<publish id='a'>/a/x</publish>" * 1000
        while stream.tell() < 50 * 1024 * 1024:
            stream.write(chunk)
        stream.write("</scope></imROS>")
    started = time.monotonic()
    found = check_file(config)
    assert time.monotonic() - started < 1.0
    assert [d.code for d in found] == ["file-too-large"]
    assert str(MAX_CONFIG_BYTES) in found[0].message


@pytest.mark.parametrize("size", [100, 2 * MAX_CONFIG_BYTES])
def test_a_json_file_where_a_configuration_goes_is_named_json(tmp_path: Path, size: int) -> None:
    """An invariants file given as the configuration (arguments swapped): too large or not,
    the error says it is JSON."""
    config = tmp_path / "p.inv"
    config.write_text('{"format": "imrosc-invariants", "pad": "' + "x" * size + '"}')
    (found,) = check_file(config)
    assert found.code == ("xml-syntax" if size < MAX_CONFIG_BYTES else "file-too-large")
    assert found.message.endswith(
        "it is JSON, not an imROS XML configuration (an invariants file?)"
    )


def test_non_utf8_bytes_point_at_the_bad_byte(tmp_path: Path) -> None:
    config = tmp_path / "latin1.xml"
    config.write_bytes(BODY.replace("/a/x", "/a/caf\xe9").encode("latin-1"))
    started = time.monotonic()
    found = check_file(config, label="latin1.xml")
    assert time.monotonic() - started < 1.0
    assert [d.as_text() for d in found] == [
        "latin1.xml:1:49: error: file is not valid UTF-8: byte 0xe9 cannot start or continue "
        "a character [encoding-error]"
    ]


def test_utf8_bom_and_declaration_are_accepted() -> None:
    data = b'\xef\xbb\xbf<?xml version="1.0" encoding="UTF-8"?>\n' + BODY.encode()
    config, problems = parse_config_bytes(data, "bom.xml")
    assert problems == []
    assert config is not None and config.root.tag == "imROS"


def test_positions_point_at_start_tags_not_their_ends() -> None:
    data = (
        b'<imROS\n  project="p">\n  <scope\n     ><publish\n id="a">/a/x</publish></scope></imROS>'
    )
    config, _ = parse_config_bytes(data, "multi.xml")
    assert config is not None
    scope = config.root[0]
    assert config.element_position(scope) == (3, 3)
    assert config.attribute_position(scope[0], "id") == (5, 6)
    assert config.text_position(scope[0]) == (5, 9)
