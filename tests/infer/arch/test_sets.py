"""Architecture invariants (thesis 3.4.3, Algorithm 7, Figures 3.11 and 3.12)."""

from __future__ import annotations

import pickle
from collections.abc import Sequence

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.arch import ArchitectureState, make_states, parse_variable
from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable
from imrosc.ir import Tunables

PUBS = "pubs(/a/subject_pose)"
SUBS = "subs(/a/subject_pose)"
SRVS = "srvs(/a/execute_task)"
VARIABLES = (Variable(PUBS, "set"), Variable(SUBS, "set"), Variable(SRVS, "set"))
CONTROLLERS = frozenset({"/a/car_ctrl", "/a/launch_ctrl", "/a/pid_ctrl"})

Snapshot = dict[str, frozenset[str]]


def snapshot(pubs: Sequence[str], subs: Sequence[str], srvs: Sequence[str] = ()) -> Snapshot:
    return {PUBS: frozenset(pubs), SUBS: frozenset(subs), SRVS: frozenset(srvs)}


def chunk(rows: Sequence[Snapshot], run: int = 0, start: float = 0.0) -> Samples:
    columns = {}
    for variable in VARIABLES:
        column = np.empty(len(rows), dtype=object)
        for i, row in enumerate(rows):
            column[i] = row[variable.name]
        columns[variable.name] = column
    time = start + np.arange(len(rows), dtype=np.float64)
    return Samples("arch", run, time, columns, VARIABLES)


def context(limit: float = 0.99) -> FinalizeContext:
    return FinalizeContext(Tunables(confidence=limit), VARIABLES, "arch")


def by_text(found: list[Invariant]) -> dict[str, Invariant]:
    return {inv.text: inv for inv in found}


def infer(runs: Sequence[Sequence[Snapshot]], limit: float = 0.99) -> list[Invariant]:
    state = ArchitectureState(VARIABLES)
    for run, rows in enumerate(runs):
        state.update(chunk(rows, run))
        state.end_run()
    return state.finalize(context(limit))


GOOD = snapshot(["/a/uav"], sorted(CONTROLLERS), ["/a/car"])


def test_stable_architecture_of_figure_3_11() -> None:
    found = by_text(infer([[GOOD] * 10]))
    assert set(found) == {
        "max_pubs(/a/subject_pose) = {/a/uav}",
        "min_pubs(/a/subject_pose) = {/a/uav}",
        "max_subs(/a/subject_pose) = {/a/car_ctrl, /a/launch_ctrl, /a/pid_ctrl}",
        "min_subs(/a/subject_pose) = {/a/car_ctrl, /a/launch_ctrl, /a/pid_ctrl}",
        "max_srvs(/a/execute_task) = {/a/car}",
        "min_srvs(/a/execute_task) = {/a/car}",
    }
    inv = found["max_pubs(/a/subject_pose) = {/a/uav}"]
    assert inv.family == "architecture"
    assert inv.kind == "max_pubs"
    assert inv.variables == (PUBS,)
    assert inv.params == {"resource": "/a/subject_pose", "nodes": ["/a/uav"]}
    assert inv.samples == 10
    assert inv.confidence == 1 - 2**-10


def test_killed_node_shrinks_min_subs_and_extra_publisher_grows_max_pubs() -> None:
    killed = snapshot(["/a/uav"], ["/a/launch_ctrl", "/a/pid_ctrl"], ["/a/car"])
    wrong = snapshot(["/a/uav", "/a/car"], ["/a/launch_ctrl", "/a/pid_ctrl"], ["/a/car"])
    # Run 1 is healthy; in run 2 /a/car_ctrl dies at snapshot 3 and /a/car publishes on
    # /a/subject_pose at snapshot 5 (the dashed lines of Figure 3.11).
    runs = [[GOOD] * 10, [GOOD] * 3 + [killed] * 2 + [wrong] + [killed] * 10]
    found = infer(runs)
    texts = by_text(found)
    assert "min_subs(/a/subject_pose) = {/a/launch_ctrl, /a/pid_ctrl}" in texts
    assert "max_subs(/a/subject_pose) = {/a/car_ctrl, /a/launch_ctrl, /a/pid_ctrl}" in texts
    assert "max_pubs(/a/subject_pose) = {/a/car, /a/uav}" in texts
    assert "min_pubs(/a/subject_pose) = {/a/uav}" in texts
    # Changes happened at snapshots 13 (kill) and 15 (extra publisher) of 26.
    assert texts["min_subs(/a/subject_pose) = {/a/launch_ctrl, /a/pid_ctrl}"].confidence == (
        1 - 2**-13
    )
    assert texts["max_pubs(/a/subject_pose) = {/a/car, /a/uav}"].confidence == 1 - 2**-11
    assert texts[
        "max_subs(/a/subject_pose) = {/a/car_ctrl, /a/launch_ctrl, /a/pid_ctrl}"
    ].confidence == (1 - 2**-26)


def test_a_late_change_is_not_justified() -> None:
    extra = snapshot(["/a/uav", "/a/car"], sorted(CONTROLLERS), ["/a/car"])
    found = by_text(infer([[GOOD] * 20 + [extra] + [GOOD] * 3]))
    assert not any(text.startswith("max_pubs") for text in found)
    assert "min_pubs(/a/subject_pose) = {/a/uav}" in found


def test_missing_resource_is_the_empty_set_and_empty_sets_are_reported() -> None:
    runs = [[snapshot([], ["/x"])] * 8]
    found = by_text(infer(runs))
    assert "max_pubs(/a/subject_pose) = {}" in found
    assert "min_srvs(/a/execute_task) = {}" in found


def test_make_states_needs_the_family_and_set_variables() -> None:
    families = frozenset({"architecture"})
    assert make_states(VARIABLES, Tunables(), frozenset({"bounds"})) == []
    assert make_states((Variable("x", "float"),), Tunables(), families) == []
    (state,) = make_states((*VARIABLES, Variable("x", "float")), Tunables(), families)
    assert state.family == "architecture"
    assert parse_variable("srvs(/s)") == ("srvs", "/s")
    assert parse_variable("len(x)") is None


def test_state_pickles_mid_run() -> None:
    state = ArchitectureState(VARIABLES)
    state.update(chunk([GOOD] * 4))
    copy = pickle.loads(pickle.dumps(state))
    for target in (state, copy):
        target.update(chunk([GOOD] * 4, start=4))
        target.end_run()
    assert state.finalize(context()) == copy.finalize(context())


NODES = ["/n1", "/n2", "/n3", "/n4"]
snapshots = st.lists(
    st.builds(
        snapshot,
        st.lists(st.sampled_from(NODES), max_size=3),
        st.lists(st.sampled_from(NODES), max_size=3),
        st.lists(st.sampled_from(NODES), max_size=1),
    ),
    max_size=12,
)


def split(rows: list[Snapshot], cuts: list[int]) -> list[list[Snapshot]]:
    points = sorted({min(c, len(rows)) for c in cuts})
    pieces, last = [], 0
    for point in [*points, len(rows)]:
        pieces.append(rows[last:point])
        last = point
    return pieces


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(snapshots, st.lists(st.integers(0, 12), max_size=3)), max_size=4),
    st.sampled_from([0.0, 0.9, 0.99]),
)
def test_fold_equals_merge(runs: list[tuple[list[Snapshot], list[int]]], limit: float) -> None:
    folded = ArchitectureState(VARIABLES)
    merged = ArchitectureState(VARIABLES)
    for run, (rows, cuts) in enumerate(runs):
        for piece in split(rows, cuts):
            folded.update(chunk(piece, run))
        folded.end_run()
        alone = ArchitectureState(VARIABLES)
        alone.update(chunk(rows, run))
        alone.end_run()
        merged.merge(pickle.loads(pickle.dumps(alone)))
    assert folded.finalize(context(limit)) == merged.finalize(context(limit))
    every = [row for rows, _ in runs for row in rows]
    for name in (PUBS, SUBS, SRVS):
        assert reference([row[name] for row in every]) == (
            *folded.sets(name),
            folded.resources[name].count - folded.resources[name].max_changed(),
            folded.resources[name].count - folded.resources[name].min_changed(),
        )


def reference(cells: list[frozenset[str]]) -> tuple[frozenset[str], frozenset[str], int, int]:
    """Algorithm 7 sample by sample, with the samples since each set last changed."""
    most: frozenset[str] = frozenset()
    least: frozenset[str] = frozenset()
    since_most = since_least = 0
    for i, cell in enumerate(cells):
        grown = most | cell if i else cell
        shrunk = least & cell if i else cell
        since_most = 1 if i == 0 or grown != most else since_most + 1
        since_least = 1 if i == 0 or shrunk != least else since_least + 1
        most, least = grown, shrunk
    return most, least, since_most, since_least
