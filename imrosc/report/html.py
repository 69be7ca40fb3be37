"""Self-contained HTML reports: one file, inline CSS, inline SVG, no script, no link.

The templates under ``templates/`` only place prepared values (``imrosc.report.views``
for tables, ``imrosc.report.svg`` for charts); every string they place is HTML-escaped.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined

import imrosc
from imrosc.report import svg, views


@functools.cache
def environment() -> Environment:
    """The Jinja2 environment of the report templates: autoescaping, strict."""
    return Environment(
        loader=PackageLoader("imrosc.report", "templates"),
        autoescape=True,
        undefined=StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )


@dataclass(frozen=True)
class Generator:
    """What the first line of a report says made it, and from what."""

    version: str
    source: str
    title: str


def generator(source: str, title: str) -> Generator:
    """The generator line's values; the source kept on one line (the comment is line one)."""
    return Generator(
        version=imrosc.__version__,
        source=" ".join(source.splitlines()),
        title=title,
    )


@dataclass(frozen=True)
class RunSection:
    """A run of a replay report with its charts."""

    run: views.Run
    anchor: str
    timeline: svg.TimelineChart | None
    polygons: list[svg.PolygonChart]
    frequencies: list[svg.FrequencyChart]

    @property
    def status(self) -> str:
        """The CSS class of the run's summary: ``bad`` if violated or unreadable, else ``ok``."""
        return "bad" if self.run.violated or self.run.error is not None else "ok"


def _run_section(index: int, run: views.Run) -> RunSection:
    return RunSection(
        run=run,
        anchor=f"run-{index}",
        timeline=svg.timeline_chart(run) if run.episodes else None,
        polygons=[svg.polygon_chart(p, run.start) for p in run.polygons],
        frequencies=[svg.frequency_chart(p, run.start, run.duration) for p in run.frequencies],
    )


def replay(document: Mapping[str, Any]) -> str:
    """The HTML report of a replay document."""
    view = views.replay(document)
    title = f"imrosc replay: {view.project or view.invariants}"
    return (
        environment()
        .get_template("replay.html.j2")
        .render(
            generator=generator(view.invariants, title),
            view=view,
            runs=[_run_section(i, r) for i, r in enumerate(view.runs, start=1)],
        )
    )


@dataclass(frozen=True)
class FamilySection:
    """A row of the per-family table with its bar chart."""

    family: views.Family
    chart: svg.SmallBars


def _family_chart(view: views.Classify, family: views.Family) -> svg.SmallBars:
    if view.compare:
        items = [("broken", family.broken, "broken"), ("unbroken", family.unbroken, "unbroken")]
    else:
        items = [("kept", family.kept, "kept"), ("total", family.total, "total")]
    return svg.small_bars(family.name, items, family.total)


def classify(document: Mapping[str, Any]) -> str:
    """The HTML report of a classify or compare document."""
    view = views.classify(document)
    title = f"imrosc {view.mode}: {view.invariants}"
    return (
        environment()
        .get_template("classify.html.j2")
        .render(
            generator=generator(view.invariants or view.config, title),
            view=view,
            families=[FamilySection(f, _family_chart(view, f)) for f in view.families],
        )
    )


def stability(document: Mapping[str, Any]) -> str:
    """The HTML report of a stability document."""
    view = views.stability(document)
    title = f"imrosc stability: {view.config}"
    return (
        environment()
        .get_template("stability.html.j2")
        .render(
            generator=generator(view.config, title),
            view=view,
            chart=svg.stability_chart(view) if view.rows else None,
        )
    )
