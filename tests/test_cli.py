"""``imrosc check`` and ``imrosc demo`` as a user runs them: outputs, formats, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from imrosc.cli import main

ROOT = Path(__file__).parent.parent
EXAMPLES = sorted((ROOT / "examples").glob("*.xml"))
FIXTURES = ROOT / "tests" / "fixtures" / "check"


def invoke(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(main, list(args))
    assert result.exception is None or isinstance(result.exception, SystemExit)
    return result.exit_code, result.output


def test_examples_are_clean() -> None:
    assert len(EXAMPLES) >= 3
    code, output = invoke("check", *map(str, EXAMPLES))
    assert code == 0, output
    assert output == f"Success: no issues found in {len(EXAMPLES)} files\n"


def test_errors_exit_1_with_compiler_style_lines() -> None:
    code, output = invoke("check", str(FIXTURES / "bad-id.xml"))
    assert code == 1
    first = output.splitlines()[0]
    assert first.endswith(
        ": error: id 'Pose1' of <publish> must be lowercase letters (e.g. 'a') [bad-id]"
    )
    assert first.startswith(f"{FIXTURES / 'bad-id.xml'}:3:")


def test_warnings_pass_unless_strict() -> None:
    warned = str(FIXTURES / "unused-condition.xml")
    assert invoke("check", warned)[0] == 0
    code, output = invoke("check", "--strict", warned)
    assert code == 1
    assert ": error: condition '1' is not used by any conds [unused-condition]" in output


def test_unreadable_file_exits_2() -> None:
    code, output = invoke("check", str(ROOT / "no-such-file.xml"))
    assert code == 2
    assert "[io-error]" in output


def test_usage_error_exits_2() -> None:
    assert invoke("check")[0] == 2
    assert invoke("check", "--format", "yaml", str(EXAMPLES[0]))[0] == 2


def test_all_files_reported_sorted_and_deduplicated() -> None:
    one, two = str(FIXTURES / "duplicate-id.xml"), str(FIXTURES / "bad-name.xml")
    code, output = invoke("check", one, two, one)
    assert code == 1
    lines = [line for line in output.splitlines() if "[" in line]
    assert len(lines) == 2
    assert lines == sorted(lines)


def test_json_format() -> None:
    code, output = invoke("check", "--format", "json", str(FIXTURES / "bad-relative.xml"))
    assert code == 1
    document = json.loads(output)
    assert document["errors"] == 1 and document["warnings"] == 0 and document["files"] == 1
    (diagnostic,) = document["diagnostics"]
    assert diagnostic["code"] == "bad-relative"
    assert diagnostic["line"] == 3
    assert diagnostic["severity"] == "error"
    assert set(diagnostic) == {"path", "line", "column", "severity", "code", "message"}


def test_github_format_escapes_properties() -> None:
    code, output = invoke("check", "--format", "github", str(FIXTURES / "bad-violation.xml"))
    assert code == 1
    annotation = output.splitlines()[0]
    assert annotation.startswith("::error file=")
    assert ",line=5,col=" in annotation
    assert ",title=imrosc bad-violation::violation must read POINTS -> ACTIONS" in annotation


def test_demo_runs_check_build_and_infer_on_the_simulated_system(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    code, output = invoke("demo", "-o", str(out), "--runs", "2", "-j", "1")
    assert code == 0, output
    assert "Success: no issues found" in output
    assert f"wrote {out / 'build' / 'plan' / 'plan.json'}" in output
    assert f"wrote {out / 'landing_sim.inv'}" in output
    assert json.loads((out / "landing_sim.inv").read_text())["format"] == "imrosc-invariants"
    assert (out / "bags" / "nominal" / "nominal_mcap" / "metadata.yaml").exists()


def test_demo_refuses_a_folder_it_did_not_make(tmp_path: Path) -> None:
    (tmp_path / "mine.txt").write_text("keep me\n")
    code, output = invoke("demo", "-o", str(tmp_path))
    assert code == 2
    assert "was not made by imrosc demo" in output
    assert (tmp_path / "mine.txt").read_text() == "keep me\n"
