"""Fuzzed configurations through check -> infer -> replay on short bags never crash a
command (issue 18): no exception escapes, no traceback, every exit status is in the README's
table. A short, fixed run (derandomized, no example database); ``bench/fuzz.py`` runs more."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.pipeline_fuzz import cases, run_case, write_bags

CI = settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return write_bags(tmp_path_factory.mktemp("fuzz-bags"))


@CI
@given(data=st.data())
def test_fuzzed_configurations_never_crash_the_pipeline(
    bags: dict[str, Path], data: st.DataObject
) -> None:
    config, replayed, files = data.draw(cases(bags), label="case")
    outcome = run_case(config, bags[replayed] if replayed in bags else Path(replayed), None, files)
    assert outcome.crash is None, (outcome.crash, config.decode(errors="replace"))


def test_a_crash_is_caught_and_named(
    bags: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The harness tells a crash from a documented failure (it would find none otherwise)."""
    config = (
        '<imROS project="p"><scope><publish id="a"><topic>/out</topic><topic>/in</topic>'
        f'</publish></scope><detect inv="p.inv"><bag>{bags["train"]}</bag></detect></imROS>'
    ).encode()
    clean = run_case(config, bags["other"])
    assert clean.crash is None and clean.statuses == {"check": 0, "infer": 0, "replay": 0}

    def broken(*args: object, **kwargs: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr("imrosc.replay.replay_document", broken)
    crashed = run_case(config, bags["other"])
    assert crashed.crash is not None
    assert crashed.crash.startswith("replay: RuntimeError at test_pipeline_fuzz.py:"), crashed
