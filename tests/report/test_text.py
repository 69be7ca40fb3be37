"""Text and JSON reports: each example document against its golden text.

Set ``IMROSC_UPDATE_GOLDEN=1`` to rewrite ``fixtures/<name>.txt`` after a deliberate change.
"""

from __future__ import annotations

import json
import os
from typing import Any

import pytest

from imrosc.report import render
from tests.report.documents import DOCUMENTS, FIXTURES, load

UPDATE = os.environ.get("IMROSC_UPDATE_GOLDEN") == "1"
PAIR = "(car_pose.pose.position.x, subject_pose.pose.position.x)"


@pytest.mark.parametrize("name", DOCUMENTS)
def test_text_matches_golden(name: str) -> None:
    text = render(load(name), "text")
    golden = FIXTURES / f"{name}.txt"
    if UPDATE or not golden.exists():
        golden.write_text(text)
    assert text == golden.read_text(), f"text report of {name}.json differs from {golden.name}"


@pytest.mark.parametrize("name", DOCUMENTS)
def test_json_is_the_document_indented(name: str) -> None:
    document = load(name)
    out = render(document, "json")
    assert out == json.dumps(document, indent=1, allow_nan=False) + "\n"
    assert json.loads(out) == document


def test_episodes_read_in_time_order_relative_to_the_start(
    replay_document: dict[str, Any],
) -> None:
    lines = render(replay_document, "text").splitlines()
    episodes = [line for line in lines if line.startswith("  ") and " s  " in line]
    episodes = [line for line in episodes if not line.startswith("  ALARM")]
    assert [line.split()[0] for line in episodes] == ["12.300", "20.000", "31.250", "40.000"]
    assert "(37x until 14.100 s)" in episodes[0]
    assert "observed 4.1, expected [-2.1, 3.7]" in episodes[0]
    assert "observed nan" in episodes[3]


def test_single_violation_has_no_repeat_note(replay_document: dict[str, Any]) -> None:
    lines = render(replay_document, "text").splitlines()
    (line,) = [x for x in lines if "31.250 s" in x and not x.startswith("  ALARM")]
    assert "x until" not in line
    assert line.endswith("observed [4.2, 3.9], expected inside the 4-vertex polygon of " + PAIR)


def test_a_polygon_reads_as_its_vertices(replay_document: dict[str, Any]) -> None:
    lines = render(replay_document, "text").splitlines()
    (line,) = [x for x in lines if "31.250 s" in x and not x.startswith("  ALARM")]
    assert f"{PAIR} inside [(-2, -1), (3.5, -1), (3.5, 3), (-2, 3)] (4 vertices)  -- " in line


def test_a_run_without_violations_says_so(replay_document: dict[str, Any]) -> None:
    text = render(replay_document, "text")
    assert "bags/success/nominal.bag: 4410 messages over 42.500 s, 2 skipped, no violations" in text
    assert "bags/fail/truncated.bag: unreadable: unexpected end of file in chunk 3" in text
    assert text.endswith("3 runs, 1 with violations, 1 with alarms, 1 unreadable\n")
    assert "  ALARM 12.450 s  a  (persist)  i0123456789a" in text
    assert "  ALARM 31.250 s  v  (2 invariants together)  i5b0c61e9d2f4" in text


def test_an_alarm_of_one_invariant_together_is_singular(replay_document: dict[str, Any]) -> None:
    (alarm,) = [
        a for run in replay_document["runs"] for a in run.get("alarms", ()) if a["rule"] == "agree"
    ]
    alarm["invariants"] = alarm["invariants"][:1]
    assert "  ALARM 31.250 s  v  (1 invariant broken)  i5b0c61e9d2f4" in render(
        replay_document, "text"
    )


def test_kept_invariants_best_f_first_and_dropped_count() -> None:
    text = render(load("classify"), "text")
    lines = text.splitlines()
    kept = lines[lines.index("kept invariants, best F first:") + 2 : -1]
    assert [line.split()[9] for line in kept] == ["i77aa00bb11cc", "i0123456789a", "i5b0c61e9d2f4"]
    assert "2 invariants dropped (F below threshold 0.5)" in text
    assert "<script>" not in text.split("dropped")[0]  # dropped invariants are only counted


def test_compare_lists_broken_invariants_by_family_most_runs_first() -> None:
    lines = render(load("compare"), "text").splitlines()
    broken = lines[lines.index("broken invariants:") + 2 :]
    assert [line.split()[2] for line in broken] == [
        "i0000000000ff",
        "i0123456789a",
        "i77aa00bb11cc",
    ]
    (temporal,) = [line for line in lines if line.startswith("temporal")]
    assert temporal.split() == ["temporal", "0", "0", "0", "-"]


def test_stability_table_has_a_column_per_round() -> None:
    lines = render(load("stability"), "text").splitlines()
    (header,) = [line for line in lines if line.startswith("family")]
    assert header.split()[1:9] == ["round", "1", "round", "2", "round", "3", "round", "4"]
    (bounds,) = [line for line in lines if line.startswith("bounds")]
    assert bounds.split() == ["bounds", "3/40", "2/40", "4/41", "1/39", "2.5", "40", "6.25%"]


def test_classify_with_no_scores_renders() -> None:
    document: dict[str, Any] = {
        "format": "imrosc-classify",
        "version": 1,
        "config": "c.xml",
        "invariants": "x.inv",
        "output": None,
        "mode": "classify",
        "beta": 1.0,
        "threshold": 0.5,
        "success": [],
        "fail": [],
        "errors": [],
        "scores": [],
        "families": {},
    }
    text = render(document, "text")
    assert "no invariant kept" in text
    assert text.endswith("0 invariants dropped (F below threshold 0.5)\n")
