"""Classification (thesis 4.2): Equations 4.1-4.7 and the filter, on counts and on runs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.classify import Score, classify, run_check
from imrosc.cli import main
from imrosc.demo import example_configs
from imrosc.invariants import load
from imrosc.sim import Scenario, ScenarioKind, write_run, write_runs

# Table 4.1: % true negative, % false positive, % true positive, % false negative, precision,
# recall, F at beta 0.5, 1.0, 2.0
TABLE_4_1 = [
    (100, 0, 100, 0, 1.0, 1.0, 1.0, 1.0, 1.0),
    (0, 100, 0, 100, 0.0, 0.0, 0.0, 0.0, 0.0),
    (90, 10, 10, 90, 0.5, 0.1, 0.278, 0.167, 0.119),
    (90, 10, 50, 50, 0.833, 0.5, 0.735, 0.625, 0.543),
    (90, 10, 90, 10, 0.9, 0.9, 0.9, 0.9, 0.9),
    (50, 50, 90, 10, 0.643, 0.9, 0.682, 0.75, 0.833),
    (10, 90, 90, 10, 0.5, 0.9, 0.549, 0.643, 0.776),
]


def _runs(violating: dict[str, int], total: int, prefix: str) -> dict[Path, set[str]]:
    """``total`` runs; invariant ``k`` is violated in the first ``violating[k]`` of them."""
    return {
        Path(f"{prefix}{run}"): {k for k, n in violating.items() if run < n} for run in range(total)
    }


@pytest.mark.parametrize("beta", [0.5, 1.0, 2.0])
def test_table_4_1_comes_out_of_the_run_counts(beta: float) -> None:
    document = {
        "invariants": [
            {"id": f"i{k}", "point": "a", "family": "bounds", "kind": "range", "text": ""}
            for k in range(len(TABLE_4_1))
        ]
    }
    success = _runs({f"i{k}": row[1] // 10 for k, row in enumerate(TABLE_4_1)}, 10, "s")
    fail = _runs({f"i{k}": row[2] // 10 for k, row in enumerate(TABLE_4_1)}, 10, "f")
    scores, families = classify(document, success, fail, beta=beta, threshold=0.6)
    column = {0.5: 6, 1.0: 7, 2.0: 8}[beta]
    for score, row in zip(scores, TABLE_4_1, strict=True):
        assert score["tn"] * 10 == row[0] and score["fp"] * 10 == row[1]
        assert score["tp"] * 10 == row[2] and score["fn"] * 10 == row[3]
        assert round(score["precision"] or 0.0, 3) == row[4]
        assert round(score["recall"], 3) == row[5]
        assert round(score["fscore"], 3) == row[column]
        assert score["kept"] == (score["fscore"] >= 0.6)
    assert families == {"bounds": {"total": 7, "kept": sum(s["kept"] for s in scores)}}


def test_undefined_cases() -> None:
    assert Score(0, 5, 0, 5).precision is None and Score(0, 5, 0, 5).fscore == 0.0
    assert Score(0, 5, 0, 0).fscore is None  # no failed runs: no recall


@pytest.fixture(scope="module")
def landing(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("classify")
    source = next(p for p in example_configs() if p.name == "landing_sim.xml")
    shutil.copyfile(source, out / "landing_sim.xml")
    write_runs(out / "bags" / "nominal", runs=3, seed=0, fmt="ros1")
    write_runs(out / "bags" / "success", runs=2, seed=100, fmt="ros1")
    kinds: tuple[ScenarioKind, ...] = ("slowed", "stuck")
    for offset, kind in enumerate(kinds):
        write_run(
            out / "bags" / "fail" / f"{kind}.bag",
            seed=200 + offset,
            fmt="ros1",
            scenario=Scenario(kind),
        )
    runner = CliRunner()
    done = runner.invoke(main, ["infer", str(out / "landing_sim.xml"), "-q", "-j", "2"])
    assert done.exit_code == 0, done.output
    return out


def test_classify_writes_a_refined_file_in_the_input_format(landing: Path) -> None:
    result = run_check(landing / "landing_sim.xml", workers=2)
    report = result.report
    assert report["mode"] == "classify" and len(report["success"]) == 2
    assert len(report["fail"]) == 2 and report["errors"] == []
    assert result.refined is not None and result.output == landing / "landing_sim.refined.inv"
    kept = [s for s in report["scores"] if s["kept"]]
    assert 0 < len(kept) < len(report["scores"])
    assert all(s["fscore"] >= 0.5 for s in kept)
    assert sum(f["kept"] for f in report["families"].values()) == len(kept)
    runner = CliRunner()
    done = runner.invoke(main, ["classify", str(landing / "landing_sim.xml"), "--format", "json"])
    assert done.exit_code == 0, done.output
    refined = load(landing / "landing_sim.refined.inv")  # the input's format: it loads
    assert [i["id"] for i in refined["invariants"]] == [s["id"] for s in kept]
    assert refined["classified"]["dropped"] == len(report["scores"]) - len(kept)
    assert json.loads(done.stdout)["scores"] == report["scores"]
    # the refined file replays like any invariants file
    done = runner.invoke(
        main,
        ["replay", str(landing / "landing_sim.refined.inv"), str(landing / "bags" / "success")],
    )
    assert done.exit_code in (0, 1), done.output


def test_classify_refuses_to_overwrite_a_foreign_file(landing: Path) -> None:
    target = landing / "mine.inv"
    target.write_text("my notes\n")
    runner = CliRunner()
    done = runner.invoke(
        main, ["classify", str(landing / "landing_sim.xml"), "--refined", str(target)]
    )
    assert done.exit_code == 1
    assert "mine.inv" in done.output and target.read_text() == "my notes\n"


def test_classify_without_check_or_with_a_bad_inv(tmp_path: Path, landing: Path) -> None:
    config = tmp_path / "c.xml"
    config.write_text('<imROS project="p"><scope><publish id="a">/a</publish></scope></imROS>\n')
    runner = CliRunner()
    done = runner.invoke(main, ["classify", str(config)])
    assert done.exit_code == 1 and "has no <check>" in done.output
    assert "Traceback" not in done.output
    broken = tmp_path / "broken.inv"
    broken.write_text("{not json")
    done = runner.invoke(main, ["classify", str(landing / "landing_sim.xml"), "--inv", str(broken)])
    assert done.exit_code == 1 and "broken.inv:1:2: not JSON" in done.output
