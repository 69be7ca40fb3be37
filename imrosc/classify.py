"""The check stage (``imrosc classify``): invariants scored on good and bad runs, or compared.

Classification (thesis 4.2): every invariant is replayed on the ``<success>`` and ``<fail>``
runs. Over the successful runs it has true negatives (not violated) and false positives
(violated); over the failed runs true positives (violated) and false negatives. Equations
4.1-4.4 make these fractions of the runs, 4.5-4.7 give precision, recall and the F-score,
and invariants whose F-score is below the threshold are dropped from the refined file.
When no success run violates it and no fail run either, precision is undefined (0/0) and
the F-score is 0: an invariant that never fires detects nothing.

Comparison (thesis 5.2): the invariants of one data set replayed on another; an invariant
violated in some run of the other set is broken there.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from imrosc import __version__
from imrosc.backends.registry import GENERATED_MARK
from imrosc.bags import discover_bags
from imrosc.check import check_loaded
from imrosc.diagnostics import Diagnostic, finalize, has_errors
from imrosc.infer.engine import default_workers
from imrosc.infer.registry import group_of
from imrosc.invariants import InvariantsFileError, load
from imrosc.ir import Project
from imrosc.lower import lower
from imrosc.replay import Replayer
from imrosc.schema.loader import load_config


class CheckStageError(Exception):
    """A configuration or file the check stage cannot use (the message says why)."""


@dataclass(frozen=True)
class Score:
    """One invariant as a classifier of failed runs (Equations 4.1-4.7)."""

    violated_success: int
    success: int
    violated_fail: int
    fail: int
    beta: float = 1.0

    @property
    def rates(self) -> tuple[float, float, float, float]:
        """``(true negative, false positive, true positive, false negative)`` fractions."""
        tn = (self.success - self.violated_success) / self.success if self.success else 0.0
        fp = self.violated_success / self.success if self.success else 0.0
        tp = self.violated_fail / self.fail if self.fail else 0.0
        fn = (self.fail - self.violated_fail) / self.fail if self.fail else 0.0
        return tn, fp, tp, fn

    @property
    def precision(self) -> float | None:
        """Equation 4.5 (``None`` when nothing was violated: 0/0)."""
        _, fp, tp, _ = self.rates
        return tp / (tp + fp) if tp + fp > 0 else None

    @property
    def recall(self) -> float | None:
        """Equation 4.6 (``None`` without failed runs)."""
        _, _, tp, fn = self.rates
        return tp / (tp + fn) if tp + fn > 0 else None

    @property
    def fscore(self) -> float | None:
        """Equation 4.7; 0 when precision or recall is 0 or undefined by 0/0 violations.

        >>> [round(Score(1, 10, 9, 10, beta).fscore or 0, 3) for beta in (0.5, 1.0, 2.0)]
        [0.9, 0.9, 0.9]
        >>> round(Score(5, 10, 9, 10, 0.5).fscore or 0, 3)
        0.682
        """
        if self.recall is None:
            return None
        precision, recall = self.precision or 0.0, self.recall
        if precision == 0 or recall == 0:
            return 0.0
        b2 = self.beta * self.beta
        return (1 + b2) * precision * recall / (b2 * precision + recall)


# -- configuration and bags -----------------------------------------------------------------


def load_project(config_path: Path) -> tuple[Project | None, list[Diagnostic]]:
    """Read, check and lower a configuration."""
    config, problems = load_config(config_path)
    if config is not None:
        problems += check_loaded(config)
    if config is None or has_errors(problems):
        return None, finalize(problems)
    return lower(config), finalize(problems)


def bags_of(base: Path, entries: Sequence[str]) -> tuple[list[Path], list[Diagnostic]]:
    """The bags ``entries`` name (relative to ``base``), and diagnostics for the rest."""
    bags: list[Path] = []
    problems: list[Diagnostic] = []
    for entry in entries:
        found, bad = discover_bags(base / entry)
        bags += found
        problems += bad
    return bags, problems


def read_invariants(path: Path) -> dict[str, Any]:
    """The invariants document, or :class:`CheckStageError`."""
    try:
        return load(path)
    except InvariantsFileError as error:
        raise CheckStageError(str(error)) from None


# -- replay in worker processes --------------------------------------------------------------

_WORKER: Replayer | None = None


def _start_worker(document: Mapping[str, Any]) -> None:
    global _WORKER  # noqa: PLW0603 - one replayer per worker process
    _WORKER = Replayer(document)


def _violated(bag: Path) -> tuple[Path, set[str], str | None]:
    assert _WORKER is not None
    result = _WORKER.run(bag)
    return bag, result.violated, result.error


def violated_per_bag(
    document: Mapping[str, Any], bags: Sequence[Path], workers: int | None = None
) -> dict[Path, tuple[set[str], str | None]]:
    """Per bag, the ids of the invariants it violates (or the error that stopped it)."""
    workers = min(workers or default_workers(), max(len(bags), 1))
    if workers <= 1:
        _start_worker(document)
        found = [_violated(bag) for bag in bags]
    else:
        context = multiprocessing.get_context("fork")
        with context.Pool(workers, _start_worker, (document,)) as pool:
            found = pool.map(_violated, bags, chunksize=1)
    return {bag: (ids, error) for bag, ids, error in found}


# -- the two modes ------------------------------------------------------------------------------


def _number(value: float | None) -> float | None:
    return None if value is None else round(value, 6)


def classify(
    document: Mapping[str, Any],
    success: Mapping[Path, set[str]],
    fail: Mapping[Path, set[str]],
    *,
    beta: float,
    threshold: float,
) -> tuple[list[dict[str, Any]], dict[str, dict[str, int]]]:
    """Scores per invariant and counts per family."""
    scores: list[dict[str, Any]] = []
    families: dict[str, dict[str, int]] = {}
    for inv in document["invariants"]:
        ident = inv["id"]
        score = Score(
            sum(ident in ids for ids in success.values()),
            len(success),
            sum(ident in ids for ids in fail.values()),
            len(fail),
            beta,
        )
        fscore = score.fscore
        kept = fscore >= threshold if fscore is not None else score.violated_success == 0
        scores.append(
            {
                "id": ident,
                "point": inv["point"],
                "family": inv["family"],
                "kind": inv["kind"],
                "text": inv["text"],
                "violated_success": score.violated_success,
                "violated_fail": score.violated_fail,
                "tp": score.violated_fail,
                "fp": score.violated_success,
                "tn": score.success - score.violated_success,
                "fn": score.fail - score.violated_fail,
                "precision": _number(score.precision),
                "recall": _number(score.recall),
                "fscore": _number(fscore),
                "kept": kept,
            }
        )
        counts = families.setdefault(inv["family"], {"total": 0, "kept": 0})
        counts["total"] += 1
        counts["kept"] += int(kept)
    return scores, dict(sorted(families.items()))


def compare(
    document: Mapping[str, Any], runs: Mapping[Path, set[str]]
) -> tuple[list[dict[str, Any]], dict[str, dict[str, int]]]:
    """Broken and unbroken invariants, one by one and per family (Table 5.4)."""
    scores: list[dict[str, Any]] = []
    families: dict[str, dict[str, int]] = {}
    for inv in document["invariants"]:
        broken_in = sum(inv["id"] in ids for ids in runs.values())
        scores.append(
            {
                "id": inv["id"],
                "point": inv["point"],
                "family": inv["family"],
                "kind": inv["kind"],
                "text": inv["text"],
                "broken": broken_in > 0,
                "runs_broken": broken_in,
            }
        )
        counts = families.setdefault(inv["family"], {"total": 0, "broken": 0, "unbroken": 0})
        counts["total"] += 1
        counts["broken" if broken_in else "unbroken"] += 1
    return scores, dict(sorted(families.items()))


def refined(
    document: Mapping[str, Any], scores: Sequence[Mapping[str, Any]], report: Mapping[str, Any]
) -> dict[str, Any]:
    """The input invariants file with the dropped invariants left out (same format)."""
    by_id = {s["id"]: s for s in scores}
    out = dict(document)
    out["$comment"] = (
        f"{GENERATED_MARK} {__version__} (imrosc classify) from {report['config']}, "
        f"refining {report['invariants']}"
    )
    out["invariants"] = [
        {**inv, "score": {k: by_id[inv["id"]][k] for k in ("precision", "recall", "fscore")}}
        for inv in document["invariants"]
        if by_id[inv["id"]]["kept"]
    ]
    out["classified"] = {
        "beta": report["beta"],
        "threshold": report["threshold"],
        "success": report["success"],
        "fail": report["fail"],
        "dropped": len(scores) - len(out["invariants"]),
    }
    return out


@dataclass
class CheckResult:
    """What ``imrosc classify`` reports and writes."""

    report: dict[str, Any] = field(default_factory=dict)
    refined: dict[str, Any] | None = None
    output: Path | None = None
    diagnostics: list[Diagnostic] = field(default_factory=list)


def group_counts(document: Mapping[str, Any]) -> dict[str, int]:
    """Invariants per summary group (default, time-related, polygon, ...)."""
    found: dict[str, int] = {}
    for inv in document["invariants"]:
        group = group_of(inv["family"])
        found[group] = found.get(group, 0) + 1
    return found


def run_check(
    config_path: Path,
    *,
    inv: Path | None = None,
    output: Path | None = None,
    workers: int | None = None,
) -> CheckResult:
    """The check stage of ``config_path``: classification or comparison."""
    out = CheckResult()
    project, out.diagnostics = load_project(config_path)
    if project is None:
        return out
    check = project.check
    if check is None:
        raise CheckStageError(f"{config_path}: the configuration has no <check> element")
    base = config_path.parent
    inv_path = inv or base / check.inv
    document = read_invariants(inv_path)
    report: dict[str, Any] = {
        "$comment": f"{GENERATED_MARK} {__version__} (imrosc classify)",
        "format": "imrosc-classify",
        "version": 1,
        "config": str(config_path),
        "invariants": str(inv_path),
        "mode": check.mode,
        "beta": check.beta,
        "threshold": check.threshold,
    }
    groups = (
        {"success": check.success, "fail": check.fail}
        if check.mode == "classify"
        else {"reference": check.bags}
    )
    found: dict[str, list[Path]] = {}
    for name, entries in groups.items():
        found[name], problems = bags_of(base, entries)
        out.diagnostics += problems
        report[name] = [str(b) for b in found[name]]
    everything = [b for bags in found.values() for b in bags]
    violated = violated_per_bag(document, everything, workers)
    report["errors"] = [
        {"bag": str(bag), "error": error} for bag, (_, error) in violated.items() if error
    ]
    runs = {
        name: {b: violated[b][0] for b in bags if violated[b][1] is None}
        for name, bags in found.items()
    }
    if check.mode == "classify":
        scores, families = classify(
            document, runs["success"], runs["fail"], beta=check.beta, threshold=check.threshold
        )
        report["scores"], report["families"] = scores, families
        out.refined = refined(document, scores, report)
        out.output = output or inv_path.with_name(inv_path.stem + ".refined.inv")
        report["output"] = str(out.output)
    else:
        report["scores"], report["families"] = compare(document, runs["reference"])
    out.report = report
    return out
