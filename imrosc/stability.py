"""Stability (thesis Table 5.3): k-fold cross-validation of inference over the detect bags.

The ``<detect>`` bags are cut into ``k`` folds (contiguous in sorted order; ``k`` equal to
the number of bags is leave-one-out). For each fold the invariants are inferred from the
other bags and replayed on the held-out ones; per family, the report counts the invariants
and how many of them a held-out run violates. Stable invariants are rarely violated by a
run of the same system they were not learnt from.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imrosc.classify import CheckStageError, bags_of, load_project, observe_runs
from imrosc.detect import run_detect
from imrosc.diagnostics import Diagnostic, has_errors
from imrosc.outputs import REPORT, mark
from imrosc.progress import ProgressFactory, shared

if TYPE_CHECKING:
    from imrosc.fleet import Fleet


def folds_of(bags: Sequence[Path], folds: int) -> list[list[Path]]:
    """``bags`` cut into ``folds`` contiguous groups of near-equal size.

    >>> [len(f) for f in folds_of([Path(str(i)) for i in range(7)], 3)]
    [3, 2, 2]
    """
    size, extra = divmod(len(bags), folds)
    out, start = [], 0
    for index in range(folds):
        stop = start + size + (index < extra)
        out.append(list(bags[start:stop]))
        start = stop
    return out


def run_stability(
    config_path: Path,
    *,
    folds: int | None = None,
    workers: int | None = None,
    bags: Sequence[Path] | None = None,
    progress_factory: ProgressFactory | None = None,
    cluster: Fleet | None = None,
    before_work: Callable[[Sequence[Path]], None] | None = None,
) -> tuple[dict[str, Any] | None, list[Diagnostic]]:
    """The stability report of ``config_path``'s detect bags, or of ``bags`` (``folds``
    None: leave-one-out); one progress over every round's training and held-out bags.
    ``cluster``: each round's bags are inferred and replayed as tasks on a Dask cluster
    (:mod:`imrosc.fleet`) instead of ``workers`` local processes. ``before_work`` is called
    with the bags found, before any is read (the command refuses its report path there)."""
    project, problems = load_project(config_path)
    if project is None:
        return None, problems
    if project.detect is None:
        raise CheckStageError(f"{config_path}: the configuration has no <detect> element")
    if bags is None:
        found_bags, found = bags_of(config_path.parent, project.detect.bags)
    else:
        found_bags, found = bags_of(Path.cwd(), [str(b) for b in bags])
    bags = found_bags
    problems += found
    count = folds or len(bags)
    if len(bags) < 2 or not 2 <= count <= len(bags):
        found_text = f"{len(bags)} detect bag(s) found"
        if problems:
            found_text += f" ({len(problems)} problem(s), the first: {problems[0].as_text()})"
        raise CheckStageError(
            f"{config_path}: {found_text}; stability needs at least 2 bags and "
            f"2 <= folds <= bags (folds: {count})"
        )
    if before_work is not None:
        before_work(bags)
    progress = progress_factory(count * len(bags)) if progress_factory is not None else None
    rounds: list[dict[str, Any]] = []
    totals: dict[str, list[int]] = {}
    violations: dict[str, list[int]] = {}
    scored = 0  # the rounds that checked some held-out bag
    checked = 0  # the held-out bags they checked
    for held_out in folds_of(bags, count):
        train = [b for b in bags if b not in held_out]
        detected = run_detect(
            config_path,
            workers=workers,
            bags=train,
            progress_factory=shared(progress) if progress is not None else None,
            reducer=cluster,
            replays=cluster.replay_held_out if cluster is not None else None,
            noter=cluster.note_bags if cluster is not None else None,
        )
        for found_problem in detected.diagnostics:
            bag_level = found_problem.code.startswith("bag-")
            if bag_level and found_problem not in problems:  # each round sees the same bags
                problems.append(found_problem)
        document = detected.document
        # a bag that cannot be read is left out of the round, as infer leaves it out (its
        # error is reported, exit 1)
        other = [d for d in detected.diagnostics if not d.code.startswith("bag-")]
        if document is None or has_errors(other):
            problems += [d for d in detected.diagnostics if d not in problems]
            return None, problems
        catalog, inferred = detected.catalog, detected.result
        if catalog is None or inferred is None or len(catalog.bags) == len(inferred.failed):
            # none of its training bags could be read: invariants of nothing, which its
            # held-out bags would break none of; listed with their errors, checks nothing
            unreadable = [d for d in detected.diagnostics if d.code == "bag-error"]
            rounds.append(
                {
                    "held_out": [str(b) for b in held_out],
                    "trained_on": [str(b) for b in train],
                    "invariants": 0,
                    "errors": [{"bag": d.path, "error": d.message} for d in unreadable],
                    "violated": {},
                    "total": {},
                    "alarmed": [],
                }
            )
            continue
        outcomes = observe_runs(document, held_out, workers, progress=progress, cluster=cluster)
        violated = {bag: (o.violated, o.error) for bag, o in outcomes.items()}
        broken = set().union(*(ids for ids, _ in violated.values()))
        alarmed = sorted(str(bag) for bag, o in outcomes.items() if o.alarms)
        # a round none of whose held-out bags could be read checked nothing: listed with
        # its errors, left out of the means (its violations are unknown, not 0)
        unread = all(error is not None for _, error in violated.values())
        total: dict[str, int] = {}
        hit: dict[str, int] = {}
        for inv in document["invariants"]:
            family = inv["family"]
            total[family] = total.get(family, 0) + 1
            hit[family] = hit.get(family, 0) + int(inv["id"] in broken)
        rounds.append(
            {
                "held_out": [str(b) for b in held_out],
                "trained_on": [str(b) for b in train],
                "invariants": len(document["invariants"]),
                "errors": [
                    {"bag": str(b), "error": e} for b, (_, e) in violated.items() if e is not None
                ],
                "violated": {} if unread else dict(sorted(hit.items())),
                "total": dict(sorted(total.items())),
                "alarmed": alarmed,
            }
        )
        if unread:
            continue
        scored += 1
        checked += sum(error is None for _, error in violated.values())
        for family, number in total.items():
            totals.setdefault(family, []).append(number)
            violations.setdefault(family, []).append(hit[family])
    if not scored:  # every round trained on nothing or checked nothing
        return None, problems
    families = {}
    for family in sorted(totals):
        mean_total = sum(totals[family]) / scored
        mean_violated = sum(violations[family]) / scored
        families[family] = {
            "total_mean": round(mean_total, 3),
            "violated_mean": round(mean_violated, 3),
            "violated_ratio": round(mean_violated / mean_total, 4) if mean_total else 0.0,
        }
    report = {
        "$comment": f"{mark(REPORT)} (imrosc stability)",
        "format": "imrosc-stability",
        "version": 1,
        "config": str(config_path),
        "folds": count,
        "bags": [str(b) for b in bags],
        "rounds": rounds,
        "families": families,
        "alarmed_runs": sum(len(r["alarmed"]) for r in rounds),
        "held_out_runs": checked,
    }
    return report, problems
