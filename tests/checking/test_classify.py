"""Classification (thesis 4.2): Equations 4.1-4.7 and the filter, on counts and on runs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from imrosc.classify import Score, classify, label_onset, load_project, run_check
from imrosc.cli import main
from imrosc.demo import example_configs
from imrosc.invariants import load
from imrosc.ir import Project, from_json, to_json
from imrosc.replay import Replayer
from imrosc.report import render
from imrosc.sim import Scenario, ScenarioKind, write_run, write_runs
from tests.checking import onsets
from tests.translate import msg, write_bag

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
    scores, families, chosen = classify(
        document, success, fail, beta=beta, threshold=0.6, select="fscore"
    )
    assert chosen is None
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
    assert done.exit_code in (0, 1, 3), done.output


def test_classify_refuses_to_overwrite_a_foreign_file(landing: Path) -> None:
    target = landing / "mine.inv"
    target.write_text("my notes\n")
    runner = CliRunner()
    done = runner.invoke(
        main, ["classify", str(landing / "landing_sim.xml"), "--refined", str(target)]
    )
    assert done.exit_code == 2  # refused before any work
    assert "mine.inv" in done.output and target.read_text() == "my notes\n"


def test_classify_without_check_or_with_a_bad_inv(tmp_path: Path, landing: Path) -> None:
    config = tmp_path / "c.xml"
    config.write_text('<imROS project="p"><scope><publish id="a">/a</publish></scope></imROS>\n')
    runner = CliRunner()
    done = runner.invoke(main, ["classify", str(config)])
    assert done.exit_code == 2 and "has no <check>" in done.output
    assert "Traceback" not in done.output
    broken = tmp_path / "broken.inv"
    broken.write_text("{not json")
    done = runner.invoke(main, ["classify", str(landing / "landing_sim.xml"), "--inv", str(broken)])
    assert done.exit_code == 2 and "broken.inv:1:2: not JSON" in done.output


# -- onset-aware classification ---------------------------------------------------------------

CLASSIFY_FIXTURES = Path(__file__).parents[1] / "fixtures" / "classify"
ALFA = Path("/work/shared/data/real/alfa")
needs_alfa = pytest.mark.skipif(not (ALFA / "onsets.json").is_file(), reason="ALFA data missing")


def test_a_violation_before_the_onset_is_a_false_positive() -> None:
    document = {
        "invariants": [
            {"id": i, "point": "a", "family": "bounds", "kind": "range", "text": ""}
            for i in ("early", "late", "both")
        ]
    }
    success = {Path("s"): set[str]()}
    fail = {Path("f"): {"late", "both"}}  # broken at or after the onset
    before = {Path("f"): {"early", "both"}}  # broken before it: a nominal run's violation
    scores, _, _ = classify(
        document, success, fail, beta=1.0, threshold=0.5, before=before, delays={"late": [0.5]}
    )
    early, late, both = scores
    assert (early["tp"], early["fp"], early["tn"], early["fn"]) == (0, 1, 1, 1)
    assert (late["tp"], late["fp"], late["tn"], late["fn"]) == (1, 0, 2, 0)
    assert (both["tp"], both["fp"], both["tn"], both["fn"]) == (1, 1, 1, 0)
    assert [s["fp_before_onset"] for s in scores] == [1, 0, 1]
    assert late["delay_mean"] == 0.5 and early["delay_mean"] is None
    assert late["fscore"] == 1.0 and both["precision"] == pytest.approx(2 / 3, abs=1e-6)


@pytest.fixture(scope="module")
def prepared(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Bags with a fault at 12 s and the invariants of their nominal runs."""
    folder = tmp_path_factory.mktemp("onsets")
    onsets.project(folder, '<fail onset="12">bags/bad</fail>')
    return folder


def _by_bag(report: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {Path(r["bag"]).name: r for r in report["runs"]}


def _same_scoring(report: dict[str, Any]) -> None:
    runs = _by_bag(report)
    assert runs["s0.bag"]["false_alarm"] is False and runs["s0.bag"]["alarms"] == 0
    late, glitch, other = runs["late.bag"], runs["glitch.bag"], runs["other.bag"]
    assert late["onset"] == glitch["onset"] == other["onset"] == onsets.ONSET
    assert late["first_alarm"] == late["detection"] == onsets.ONSET and late["delay"] == 0.0
    assert other["detection"] == onsets.ONSET and other["false_alarm"] is False
    assert late["false_alarm"] is False and late["alarms_before_onset"] == 0
    assert glitch["first_alarm"] == 3.0 and glitch["false_alarm"] is True
    assert glitch["detected"] is True and glitch["delay"] == 0.0
    assert report["detection"] == {
        "success_runs": 1,
        "fail_runs": 3,
        "with_onset": 3,
        "detected": 3,
        "recall": 1.0,
        "false_alarm_success": 0,
        "false_alarm_fail": 1,
        "false_alarm_rate": 0.25,
        "delay_mean": 0.0,
        "delay_max": 0.0,
    }
    bound = next(s for s in report["scores"] if s["family"] == "bounds")
    # the glitch's pre-onset half is a nominal run that breaks the bound: one false positive
    assert (bound["tp"], bound["fp"], bound["tn"], bound["fn"]) == (3, 1, 3, 0)
    assert bound["fp_before_onset"] == 1 and bound["delay_mean"] == 0.0


@pytest.mark.parametrize(
    "fail",
    [
        '<fail onset="12">bags/bad</fail><fail onset="12">bags/other</fail>',
        '<fail onset_topic="/failure_status">bags/bad</fail>'
        '<fail onset_topic="/failure_status">bags/other</fail>',
        '<fail onset_topic="failure_status">bags/bad</fail>'  # relative: resolved
        '<fail onset_topic="failure_status">bags/other</fail>',
        '<fail onsets="onsets.json">bags/bad</fail><fail onsets="onsets.json">bags/other</fail>',
    ],
    ids=["seconds", "topic", "relative-topic", "file"],
)
def test_the_three_ways_of_giving_the_onset_score_alike(
    prepared: Path, tmp_path: Path, fail: str
) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    (folder / "onsets.json").write_text(
        json.dumps(
            {
                "bags/bad/late.bag": 12,
                "bags/bad/glitch.bag": {"onset_s": 12.0},
                "bags/other/other.bag": 12,
            }
        )
    )
    config = onsets.project(folder, fail)
    result = run_check(config, workers=1)
    assert [d for d in result.diagnostics if d.code != "relative-name"] == []
    _same_scoring(result.report)


def test_without_an_onset_the_whole_fail_run_counts(prepared: Path, tmp_path: Path) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    report = run_check(onsets.project(folder, "<fail>bags/bad</fail>"), workers=1).report
    bound = next(s for s in report["scores"] if s["family"] == "bounds")
    assert (bound["tp"], bound["fp"], bound["tn"], bound["fn"]) == (2, 0, 1, 0)
    assert "fp_before_onset" not in bound
    glitch = _by_bag(report)["glitch.bag"]
    assert glitch["onset"] is None and glitch["detection"] == 3.0 and glitch["delay"] is None
    assert report["detection"]["with_onset"] == 0 and report["detection"]["delay_mean"] is None


def _expected(case: Path) -> set[tuple[str, int, str, str]]:
    found = set()
    for line in (case / "classify.expect").read_text().splitlines():
        where, severity, code = line.split(": ")
        name, number = where.split(":")
        found.add((name, int(number), severity, code.strip("[]")))
    return found


@pytest.mark.parametrize(
    "case", sorted(p for p in CLASSIFY_FIXTURES.iterdir() if p.is_dir()), ids=lambda p: p.name
)
def test_classify_fixture_reports_exactly_its_expectations(
    case: Path, prepared: Path, tmp_path: Path
) -> None:
    """Each ``tests/fixtures/classify/<code>/`` runs on the prepared bags; ``classify.expect``
    lists every diagnostic as ``FILE:LINE: severity: [code]``, and ``options.json``, when
    there is one, the options of the run (``{"cross_validate": 2}``)."""
    folder = onsets.copy(prepared, tmp_path / case.name)
    shutil.copytree(case, folder, dirs_exist_ok=True)
    given = case / "options.json"
    options = json.loads(given.read_text()) if given.exists() else {}
    result = run_check(folder / "config.xml", workers=1, **options)
    got = {(Path(d.path).name, d.line, d.severity.value, d.code) for d in result.diagnostics}
    assert got == _expected(case), [d.as_text() for d in result.diagnostics]


def test_unusable_onsets_name_the_bag_and_score_the_run_whole(
    prepared: Path, tmp_path: Path
) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    shutil.copytree(CLASSIFY_FIXTURES / "onset-unusable", folder, dirs_exist_ok=True)
    done = CliRunner().invoke(main, ["classify", str(folder / "config.xml"), "--format", "json"])
    assert done.exit_code == 0, done.output
    assert "Traceback" not in done.output
    messages = done.stderr
    assert "late.bag: the onset 50 s is past the end of the bag (19.900 s)" in messages
    assert "never.bag: /failure_status never turns non-zero" in messages
    assert "glitch.bag has no topic /no_such_label" in messages
    assert "other.bag is not in the onsets file onsets.json" in messages
    runs = [r for r in json.loads(done.stdout)["runs"] if r["kind"] == "fail"]
    assert len(runs) == 4 and {r["onset"] for r in runs} == {None}
    glitch = next(r for r in runs if r["bag"].endswith("glitch.bag"))
    assert glitch["detection"] == 3.0 and glitch["false_alarm"] is False  # scored whole


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("{not json", "the onsets file is not JSON"),
        ("[1, 2]", "must map bag paths to onsets"),
        ('{"bags/bad/late.bag": -4}', "expected seconds >= 0 or null"),
        ('{"bags/bad/late.bag": {"onset_s": "soon"}}', "expected seconds >= 0 or null"),
        (None, "cannot read the onsets file"),
    ],
)
def test_a_bad_onsets_file_is_one_line(
    prepared: Path, tmp_path: Path, content: str | None, message: str
) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    if content is not None:
        (folder / "onsets.json").write_text(content)
    config = onsets.project(folder, '<fail onsets="onsets.json">bags/bad</fail>')
    done = CliRunner().invoke(main, ["classify", str(config)])
    assert done.exit_code == 2 and "Traceback" not in done.output
    assert message in done.output and "onsets.json" in done.output


def test_success_runs_that_trained_the_invariants_are_scored_as_held_out(tmp_path: Path) -> None:
    fails = '<fail onset="12">bags/bad</fail><fail onset="12">bags/other</fail>'
    config = onsets.project(tmp_path, fails, success="bags/train")
    document = json.loads((tmp_path / "p.inv").read_text())
    broken: dict[str, set[str]] = {}
    for unit in document["calibration"]["held_out"]:
        broken.setdefault(str(Path(unit["bag"]).resolve()), set()).update(unit["trace"])
    assert any(broken.values())  # the calibration's held-out units broke something
    done = run_check(config, workers=1)
    assert [d.code for d in done.diagnostics] == []  # no success-in-detect: not in-sample
    report = done.report
    assert sorted(report["held_out_scored"]) == sorted(report["success"])
    for score in report["scores"]:
        assert score["fp"] - score["fp_before_onset"] == sum(
            score["id"] in ids for ids in broken.values()
        )
    success = [r for r in report["runs"] if r["kind"] == "success"]
    assert len(success) == 3 and all(r["held_out"] for r in success)
    assert all(r["first_alarm"] is None for r in success)
    assert report["detection"]["success_runs"] == 3


def test_success_runs_that_trained_the_invariants_are_cross_validated(
    prepared: Path, tmp_path: Path
) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    fails = '<fail onset="12">bags/bad</fail><fail onset="12">bags/other</fail>'
    config = onsets.project(folder, fails, success="bags/train")
    plain = run_check(config, workers=1)
    assert [d.code for d in plain.diagnostics] == ["success-in-detect"]
    assert "3 of 3 <success> bags are <detect> bags" in plain.diagnostics[0].message
    assert len(plain.report["success_in_detect"]) == 3
    done = CliRunner().invoke(
        main, ["classify", str(config), "--cross-validate", "3", "-j", "1", "--format", "json"]
    )
    assert done.exit_code == 0, done.output
    report = json.loads(done.stdout)
    cv = report["cross_validation"]
    assert cv["folds"] == 3 and len(cv["rounds"]) == 3
    assert sorted(cv["scored"]) == sorted(report["success"])
    for fold in cv["rounds"]:
        assert len(fold["held_out"]) == 1 and len(fold["trained_on"]) == 2
        assert [s["bag"] for s in fold["success"]] == fold["held_out"]
    assert report["detection"]["success_runs"] == 3
    done = CliRunner().invoke(main, ["classify", str(config), "--cross-validate", "4"])
    assert done.exit_code == 2 and "needs 2 <= K <= the 3 <detect> bag(s)" in done.output
    assert "Traceback" not in done.output


@needs_alfa
def test_alfa_onsets_come_from_the_failure_status_topic() -> None:
    """The real ALFA flights: the first non-zero /failure_status is onsets.json's onset."""
    table = json.loads((ALFA / "onsets.json").read_text())
    for key, entry in table.items():
        onset, problem = label_onset(ALFA / key, "/failure_status")
        if entry["onset_s"] is None:
            assert onset is None and problem is not None and "never turns non-zero" in problem
        else:
            assert problem is None and onset == pytest.approx(entry["onset_s"], abs=1e-3)


@needs_alfa
def test_alfa_flight_classified_with_its_label_topic(tmp_path: Path) -> None:
    nominal = sorted((ALFA / "no_failure").glob("*.bag"))
    engine = ALFA / "engine" / "carbonZ_2018-07-30-16-39-00_2_engine_failure.bag"
    config = tmp_path / "alfa.xml"
    config.write_text(
        f"""<imROS project="alfa">
  <scope><publish id="a">/alfa/merged</publish></scope>
  <detect inv="alfa.inv" discrete="0"><bag>{nominal[0]}</bag><bag>{nominal[1]}</bag></detect>
  <check inv="alfa.inv">
    <success>{nominal[2]}</success>
    <fail onset_topic="/failure_status">{engine}</fail>
    <fail onsets="{ALFA / "onsets.json"}">{ALFA / "rudder"}</fail>
  </check>
</imROS>
"""
    )
    done = CliRunner().invoke(main, ["infer", str(config), "-q", "-j", "1"])
    assert done.exit_code == 0, done.output
    result = run_check(config, workers=1)
    # every onset found (two nominal flights may leave no monitor worth keeping: a warning)
    assert {d.code for d in result.diagnostics} <= {"no-monitor-kept"}
    table = json.loads((ALFA / "onsets.json").read_text())
    runs = [r for r in result.report["runs"] if r["kind"] == "fail"]
    assert len(runs) == 4
    for run in runs:
        expected = table[str(Path(run["bag"]).relative_to(ALFA))]["onset_s"]
        assert run["onset"] == pytest.approx(expected, abs=1e-3)
        if run["detected"]:
            assert run["delay"] == pytest.approx(run["detection"] - run["onset"], abs=1e-5)
            assert run["delay"] >= 0
    detection = result.report["detection"]
    assert detection["fail_runs"] == 4 and detection["with_onset"] == 4


def test_fail_onsets_are_lowered_one_per_fail_and_round_trip() -> None:
    example = Path(__file__).parents[2] / "examples" / "uav_landing.xml"
    project, problems = load_project(example)
    assert project is not None and project.check is not None, problems
    check = project.check
    assert check.fail == ("bags/fail", "bags/fail_labelled", "bags/fail_logged")
    seconds, topic, file = check.onsets
    assert (seconds.seconds, seconds.topic, seconds.file) == (10.0, None, None)
    assert (topic.seconds, topic.topic) == (None, "/failure_status")
    assert file.file == "bags/fail_logged/onsets.json" and file.given
    assert all(o.span.line > check.span.line for o in check.onsets)
    assert from_json(Project, to_json(project)) == project


def test_a_run_whose_topic_changed_type_is_named_not_scored_silently(
    prepared: Path, tmp_path: Path
) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    drifted = [
        msg("/x", onsets.START + k / 10, "std_msgs/msg/Float32", data=5.0) for k in range(100)
    ]
    (folder / "bags" / "drift").mkdir(parents=True)
    write_bag(folder / "bags" / "drift" / "d.bag", drifted)
    config = onsets.project(folder, "<fail>bags/drift</fail>")
    done = CliRunner().invoke(main, ["classify", str(config), "-j", "1"])
    assert "Traceback" not in done.output
    assert "d.bag: warning: topic /x has type std_msgs/msg/Float32 in this bag" in done.stderr
    report = run_check(config, workers=1).report
    (run,) = [r for r in report["runs"] if r["kind"] == "fail"]
    assert run["warnings"][0].startswith("topic /x has type std_msgs/msg/Float32")
    assert run["detected"] is False and run["violated"] == 0


def test_invariants_of_another_project_are_a_warning(prepared: Path, tmp_path: Path) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    config = onsets.project(folder, '<fail onset="12">bags/bad</fail>')
    config.write_text(config.read_text().replace('project="p"', 'project="q"'))
    codes = [d.code for d in run_check(config, workers=1).diagnostics]
    assert "project-mismatch" in codes


def test_a_learnt_detector_joins_the_monitor_when_held_out_runs_say_it_is_worth_it(
    prepared: Path, tmp_path: Path
) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    config = folder / "detector.xml"
    config.write_text(
        '<imROS project="p">\n'
        '  <scope><publish id="a">/x</publish></scope>\n'
        '  <detect inv="p.inv"><bag>bags/train</bag></detect>\n'
        '  <check inv="p.inv">\n'  # detector="logistic", the default'
        "    <success>bags/ok</success><success>bags/train</success>\n"
        '    <fail onset="12">bags/bad</fail><fail onset="12">bags/other</fail>\n'
        "  </check>\n"
        "</imROS>\n"
    )
    result = run_check(config, workers=1)
    assert result.refined is not None, result.diagnostics
    (detector,) = result.report["detectors"]
    assert detector["point"] == "a" and detector["variables"] == 1
    # the jump to 5 shows in every failed run held out within the window of its onset (the
    # glitch before glitch.bag's onset, a nominal sample, raises the threshold)
    assert len(detector["detected"]) == 3
    assert all(0.0 <= delay < 1.0 for delay in detector["delays"].values())
    cover = result.report["cover"]
    assert [w["monitor"] for w in cover["held_out"]] == [
        "cover",
        "detector",
        "both",
        "inferred",
        "inferred+detector",
        "none",
    ]
    best = max(w["value"] for w in cover["held_out"])
    assert next(w for w in cover["held_out"] if w["monitor"] == cover["monitor"])["value"] == best
    kept = {inv["family"] for inv in result.refined["invariants"]}
    with_detector = ("detector", "both", "inferred+detector")
    assert ("detector" in kept) == (cover["monitor"] in with_detector)
    if "detector" in kept:
        replayed = Replayer(result.refined).run(folder / "bags" / "bad" / "late.bag")
        first = min(a.time for a in replayed.alarms) - replayed.start
        assert onsets.ONSET <= first < onsets.ONSET + 1.0


def test_detector_none_learns_no_detector(prepared: Path, tmp_path: Path) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    config = onsets.project(folder, '<fail onset="12">bags/bad</fail>')
    config.write_text(config.read_text().replace("<check ", '<check detector="none" '))
    result = run_check(config, workers=1)
    assert "detectors" not in result.report
    assert result.refined is not None
    assert all(inv["family"] != "detector" for inv in result.refined["invariants"])


def test_each_run_says_how_many_samples_each_point_checked(prepared: Path, tmp_path: Path) -> None:
    folder = onsets.copy(prepared, tmp_path / "p")
    config = onsets.project(folder, '<fail onset="12">bags/bad</fail>')
    config.write_text(config.read_text().replace("<check ", '<check detector="none" '))
    report = run_check(config, workers=1).report
    assert report["runs"] and all(run["checked"]["a"] > 0 for run in report["runs"])
    text = render(report, "text")
    assert "samples checked" in text and f"a {report['runs'][0]['checked']['a']:,}" in text


def test_the_refined_file_of_the_inferred_monitor_keeps_every_invariant_and_its_rule(
    prepared: Path, tmp_path: Path
) -> None:
    """The inferred monitor is judged by its alarms, with its own rule; kept, the refined
    file is that monitor: every invariant, and the alarm rule calibration set for all of
    them (a subset's rule is recomputed; this one is not)."""
    folder = onsets.copy(prepared, tmp_path / "p")
    config = onsets.project(folder, '<fail onset="12">bags/bad</fail><fail>bags/other</fail>')
    config.write_text(config.read_text().replace("<check ", '<check detector="none" '))
    document = load(folder / "p.inv")
    result = run_check(config, workers=1)
    assert result.refined is not None
    cover = result.report["cover"]
    by_name = {w["monitor"]: w for w in cover["held_out"]}
    # its alarms: late.bag and other.bag from the jump on; glitch.bag's glitch at 3 s comes
    # before the onset; 1 alarm-free of 6 held-out units and 1 untrained run: 1/9
    assert (by_name["inferred"]["detected"], by_name["inferred"]["early"]) == (2, 1)
    assert len(document["calibration"]["held_out"]) == 6
    runs = len(result.report["runs"])
    assert by_name["inferred"]["expected_false_alarms"] == pytest.approx(runs / 9, abs=1e-6)
    # the cover, chosen without each held-out failed run, detects none of them
    assert by_name["cover"]["value"] < by_name["inferred"]["value"]
    assert cover["monitor"] == "inferred"
    assert [i["id"] for i in result.refined["invariants"]] == [
        i["id"] for i in document["invariants"]
    ]
    assert result.refined["alarms"] == document["alarms"]
