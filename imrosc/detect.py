"""The detect stage (``imrosc infer``): configuration and bags in, invariants file out.

1. check and lower the configuration; 2. catalog the ``<detect>`` bags (bad bags are
reported and skipped); 3. run the passes with the bags as graph source (both steps through
:mod:`imrosc.frontend`) and render the plan and job of ``imrosc build --backend plan`` with
the bags as type source, in memory; 4. infer over the good bags in worker
processes; 5. write the invariants file next to the configuration.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from imrosc import ir
from imrosc.backends.plan import render_job, render_plan
from imrosc.backends.registry import BuildInputs, TopicType
from imrosc.build import load_graph, without_graph_errors
from imrosc.calibrate import Calibration, calibrate
from imrosc.calibrate.rule import Replays
from imrosc.diagnostics import Diagnostic, finalize, has_errors, make
from imrosc.formats.job import JobDocument
from imrosc.formats.plan import PlanDocument, PlanPoint
from imrosc.frontend import lowered, passed
from imrosc.infer.engine import (
    BagReducer,
    Discovered,
    InferenceResult,
    Progress,
    default_workers,
    infer,
)
from imrosc.infer.registry import group_of
from imrosc.invariants import PointInfo, document
from imrosc.remote import bag_path
from imrosc.runtime.families import INFERRED_GROUPS
from imrosc.runtime.points import Filter
from imrosc.translate.catalog import Catalog, Noter, build_catalog, note_in_pool
from imrosc.translate.layout import TopicLayout
from imrosc.translate.points import PointSpec, point_specs

_LABELS = {"nan": "NaN", "+inf": "+inf", "-inf": "-inf"}


@dataclass
class DetectResult:
    """Everything ``imrosc infer`` reports."""

    diagnostics: list[Diagnostic] = field(default_factory=list)
    document: dict[str, Any] | None = None
    output: Path | None = None
    catalog: Catalog | None = None
    result: InferenceResult | None = None
    skipped_points: list[str] = field(default_factory=list)
    seconds: float = 0.0
    """Seconds to infer (calibration apart)."""
    calibration_seconds: float = 0.0
    calibration: Calibration | None = None

    @property
    def ok(self) -> bool:
        return self.document is not None and not has_errors(self.diagnostics)

    def nonfinite(self) -> list[str]:
        """One line per point whose training samples held NaN or infinite values (left out
        by inference), naming its variables and how many of each (conditional points found
        in the data repeat their point's and are not listed)."""
        lines = []
        for key, point in (self.document or {}).get("points", {}).items():
            found = point.get("support", {}).get("nonfinite")
            if not found:
                continue
            parts = []
            for name, counts in found.items():
                shown = [f"{n:,} {_LABELS[label]}" for label, n in counts.items() if n]
                parts.append(f"{name}: {', '.join(shown)}")
            samples = point["support"]["samples"]
            lines.append(
                f"non-finite values left out of point {key} (of {samples:,} samples): "
                + "; ".join(parts)
            )
        return lines

    def counts(self) -> dict[str, int]:
        """Invariants per summary group, in the thesis' order."""
        found = dict.fromkeys(INFERRED_GROUPS, 0)
        for invariant in (self.document or {}).get("invariants", ()):
            group = group_of(invariant["family"])
            found[group] = found.get(group, 0) + 1
        return found


def _compile(
    lowered: ir.Project, graph_files: Sequence[Path], catalog: Catalog
) -> tuple[ir.Project, PlanDocument, JobDocument, list[Diagnostic]]:
    graph, found = load_graph(graph_files, catalog.bags, read=catalog.bag_graphs())
    problems = [d for d in found if d.code != "bag-error"]  # the catalog reported bad bags
    project, found_passes = passed(lowered, graph)
    problems += found_passes
    types = {t: TopicType(m, f) for t, (m, f) in catalog.types.items()}
    inputs = BuildInputs(project, tuple(str(b) for b in catalog.bags), types)
    return project, render_plan(inputs), render_job(inputs), problems


def _discovered(found: Discovered | None) -> tuple[Filter, ...]:
    """The condition inference discovered for a point, as the engine filters on it."""
    return () if found is None else (Filter(variable=found.variable, value=found.value),)


def _points(specs: Sequence[PointSpec], result: InferenceResult) -> list[PointInfo]:
    infos = []
    discovered = {d.key: d for d in result.discovered}
    for key, state in result.states.items():
        spec = state.spec
        found = discovered.get(key)
        condition = spec.condition.id if spec.condition else (found.text if found else None)
        infos.append(
            PointInfo(
                key,
                spec.kind,
                spec.trigger,
                condition,
                state.samples,
                state.runs,
                spec.variables,
                spec.pairing(*_discovered(found)),
                None if found else {k: tuple(v) for k, v in state.nonfinite.items()},
            )
        )
    return infos


@dataclass
class Prepared:
    """A checked, compiled configuration and its catalogued bags, ready to translate."""

    project: ir.Project
    base: Path
    catalog: Catalog
    specs: list[PointSpec]
    layouts: dict[str, TopicLayout]
    skipped_points: list[str]


def prepare(
    config_path: Path,
    *,
    graph_files: Sequence[Path] = (),
    bags: Sequence[Path] | None = None,
    noter: Noter | None = None,
) -> tuple[Prepared | None, list[Diagnostic]]:
    """Check and compile the configuration against its bags (or ``bags``), catalogued by
    ``noter`` (:func:`~imrosc.translate.catalog.build_catalog`; this process by default)."""
    lowered_project, problems = lowered(config_path)
    if lowered_project is None:
        return None, finalize(problems)
    base = config_path.parent
    detect = lowered_project.detect
    if bags is None:
        bags = [bag_path(b, base) for b in detect.bags] if detect else []
    catalog = build_catalog(bags, noter)
    project, plan, job, found = _compile(lowered_project, graph_files, catalog)
    unread = any(d.code == "bag-error" for d in catalog.diagnostics)
    if unread and not catalog.bags and not graph_files:  # the bags were the graph source
        found = without_graph_errors(found)
    problems = finalize(problems + found + catalog.diagnostics)
    if has_errors(found):
        return None, problems
    specs, skipped, layouts = point_specs(plan, job, catalog)
    used = {name for point in plan["points"] for name in _topics_of(point)}
    for topic, (bag, message) in sorted(catalog.unusable.items()):
        if topic in used:
            problems.append(make(str(bag), 1, 1, "bag-error", message))
    for topic, drifted in sorted(catalog.drift.items()):
        if topic in used:
            problems += [make(str(bag), 1, 1, "bag-type-drift", text) for bag, text in drifted]
    return Prepared(project, base, catalog, specs, layouts, skipped), finalize(problems)


def _topics_of(point: PlanPoint) -> set[str]:
    """Every topic a plan point reads."""
    topics: set[str] = set()
    if point["kind"] == "publish":
        topics |= {point["trigger"]["topic"], *(i["topic"] for i in point["inputs"])}
    elif point["kind"] == "temporal":
        topics |= {e["name"] for e in point["events"]}
    if point["condition"]:
        topics.add(point["condition"]["topic"])
    return topics - {""}


def run_detect(
    config_path: Path,
    *,
    workers: int | None = None,
    graph_files: Sequence[Path] = (),
    bags: Sequence[Path] | None = None,
    progress_factory: Callable[[int], Progress] | None = None,
    budget: float | None = None,
    before_work: Callable[[Path, Sequence[Path]], None] | None = None,
    reducer: BagReducer | None = None,
    replays: Replays | None = None,
    noter: Noter | None = None,
) -> DetectResult:
    """Run the detect stage; the invariants document is returned, not yet written.
    ``budget`` overrides the configuration's false-alarm budget (0: no calibration).
    ``before_work`` is called with the default invariants file (``<detect inv>``) and the
    bags, once the configuration is checked and before any bag is read (the command line
    refuses an output there, not after minutes of work). ``reducer`` runs the bags elsewhere
    (a Dask cluster, :mod:`imrosc.fleet`) instead of ``workers`` local processes,
    ``replays`` calibration's held-out replays and ``noter`` the catalogue's pre-pass over
    the bags (without a reducer, the ``workers`` processes read it too)."""
    started = time.monotonic()
    out = DetectResult()
    if noter is None and reducer is None:
        noter = note_in_pool(workers or default_workers())
    prepared, out.diagnostics = prepare(
        config_path, graph_files=graph_files, bags=bags, noter=noter
    )
    if prepared is None:
        return out
    project, catalog, specs, layouts = (
        prepared.project,
        prepared.catalog,
        prepared.specs,
        prepared.layouts,
    )
    out.catalog, out.skipped_points = catalog, prepared.skipped_points
    inv = project.detect.inv if project.detect else f"{project.name}.inv"
    if before_work is not None:
        before_work(prepared.base / inv, catalog.bags)
    tunables = project.detect.tunables if project.detect else ir.Tunables()
    if budget is not None:
        tunables = replace(tunables, budget=budget)
    progress = progress_factory(len(catalog.bags)) if progress_factory else None
    result = infer(
        catalog.bags,
        specs,
        layouts,
        catalog.callerids,
        tunables,
        workers=workers or default_workers(),
        progress=progress,
        calibrate=tunables.budget > 0,
        reducer=reducer,
    )
    out.result = result
    for bag, reason in sorted(result.failed.items()):
        out.diagnostics.append(make(str(bag), 1, 1, "bag-error", reason))
    for bag in result.empty:
        message = "no message on the configured topics; the bag adds no samples"
        out.diagnostics.append(make(str(bag), 1, 1, "bag-empty", message))
    topics = {
        topic: {
            "type": layout.msgtype,
            "variables": [
                {"name": v.name, "path": v.path, "type": v.type, "derived": v.derived}
                for v in layout.variables
            ],
        }
        for topic, layout in layouts.items()
    }
    out.document = document(
        project=project.name,
        source=str(config_path),
        bags=[str(b) for b in catalog.bags if b not in result.failed],
        tunables=ir.to_json(tunables),
        topics=topics,
        points=_points(specs, result),
        invariants=result.invariants(tunables),
    )
    out.seconds = time.monotonic() - started
    if tunables.budget > 0:
        out.calibration = calibrate(
            out.document,
            result.units,
            tunables.budget,
            workers=workers or default_workers(),
            step_tail=tunables.step_tail,
            replays=replays,
        )
        out.calibration_seconds = time.monotonic() - started - out.seconds
    out.output = prepared.base / inv
    return out
