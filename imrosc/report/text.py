"""Plain-text reports: aligned tables and timelines for a terminal or a log."""

from __future__ import annotations

from collections.abc import Sequence

from imrosc.report.values import plural
from imrosc.report.views import Classify, Replay, Stability


def table(headers: Sequence[str], rows: Sequence[Sequence[str]], align: str = "l") -> list[str]:
    """Columns two spaces apart, aligned by ``align``: ``l`` left, ``r`` right, then right.

    >>> print("\\n".join(table(["family", "total"], [["bounds", "120"], ["frequency", "5"]])))
    family     total
    bounds       120
    frequency      5
    """
    widths = [len(h) for h in headers]
    for row in rows:
        widths = [max(w, len(c)) for w, c in zip(widths, row, strict=True)]
    lines = []
    for row in [headers, *rows]:
        cells = [
            c.ljust(w) if a == "l" else c.rjust(w)
            for c, w, a in zip(row, widths, align.ljust(len(widths), "r"), strict=True)
        ]
        lines.append("  ".join(cells).rstrip())
    return lines


ALARMS_SHOWN = 20
"""Alarms listed per run in a text report (all are in the JSON report)."""


def replay(view: Replay) -> str:
    """A replay report: per run a header line and the timeline of its episodes."""
    title = f"imrosc replay of {view.invariants}"
    if view.project:
        title += f" (project {view.project})"
    lines = [title]
    for run in view.runs:
        lines += ["", f"{run.bag}: {run.summary}"]
        if run.error is not None:
            continue
        for alarm in run.alarms[:ALARMS_SHOWN]:
            together = f"{plural(alarm.invariants, 'invariant')} together"
            why = together if alarm.rule == "agree" else alarm.rule
            lines.append(
                f"  ALARM {alarm.time}  {alarm.point}  ({why})  {alarm.invariant}  {alarm.text}"
            )
        if len(run.alarms) > ALARMS_SHOWN:
            lines.append(f"  ... {len(run.alarms) - ALARMS_SHOWN} more alarms")
        lines += [f"  warning: {w}" for w in run.warnings]
        if run.checked:
            counts = ", ".join(f"{point} {count:,}" for point, count in run.checked.items())
            lines.append(f"  samples checked: {counts}")
        if not run.episodes:
            if run.violated:  # violations counted without episodes: say so, list nothing
                lines.append("  no episodes recorded")
            continue
        time_width = max(len(e.time) for e in run.episodes)
        point_width = max(len(e.point) for e in run.episodes)
        id_width = max(len(e.invariant) for e in run.episodes)
        category_width = max(len(e.category) for e in run.episodes)
        for e in run.episodes:
            line = (
                f"  {e.time.rjust(time_width)}  {e.point.ljust(point_width)}"
                f"  {e.invariant.ljust(id_width)}  {e.category.ljust(category_width)}  {e.text}"
            )
            detail = " ".join(p for p in (e.comparison, e.repeat) if p)
            lines.append(f"{line}  -- {detail}" if detail else line)
    lines += ["", view.summary]
    return "\n".join(lines) + "\n"


def _errors(view: Classify) -> list[str]:
    if not view.errors:
        return []
    lines = ["", "unreadable bags:"]
    lines += [f"  {e.bag}: {e.error}" for e in view.errors]
    return lines


def classify(view: Classify) -> str:
    """A classify report (kept invariants by F-score) or a compare report (broken ones)."""
    lines = [f"imrosc {view.mode} of {view.invariants} ({view.config})", view.summary]
    if view.output:
        lines.append(f"refined invariants written to {view.output}")
    if view.success_warning:
        lines.append(f"warning: {view.success_warning}")
    lines += _errors(view)
    lines.append("")
    if view.compare:
        rows = [
            [f.name, str(f.total), str(f.broken), str(f.unbroken), f.broken_share]
            for f in [*view.families, view.all]
        ]
        lines += table(["family", "total", "broken", "unbroken", "% broken"], rows)
        lines.append("")
        broken = view.broken
        if not broken:
            lines.append("no invariant broken")
        else:
            lines.append("broken invariants:")
            runs = len(view.reference)
            rows = [[s.family, s.point, s.id, f"{s.runs_broken} of {runs}", s.text] for s in broken]
            headers = ["family", "point", "id", "runs broken", "text"]
            lines += ["  " + line for line in table(headers, rows, "lllrl")]
        return "\n".join(lines) + "\n"
    rows = [[f.name, str(f.total), str(f.kept)] for f in [*view.families, view.all]]
    lines += table(["family", "total", "kept"], rows)
    lines.append("")
    kept = view.kept
    if kept:
        lines.append("kept invariants, best F first:")
        rows = [
            [
                *(s.fscore, s.precision, s.recall, s.tp, s.fp, s.tn, s.fn),
                *(s.family, s.point, s.id, s.text),
            ]
            for s in kept
        ]
        headers = ["F", "P", "R", "TP", "FP", "TN", "FN", "family", "point", "id", "text"]
        lines += ["  " + line for line in table(headers, rows, "rrrrrrrllll")]
    else:
        lines.append("no invariant kept")
    if view.cover:
        lines.append(view.cover)
    lines.append(view.dropped_line)
    lines += _runs(view)
    return "\n".join(lines) + "\n"


def _runs(view: Classify) -> list[str]:
    """The run level: each run's alarms against its fault's onset, then the summary."""
    if not view.runs:
        return []
    lines = ["", "runs (alarms; times from each run's start):"]
    rows = [
        [
            r.kind,
            r.bag,
            r.onset,
            r.first_alarm,
            r.detection,
            r.delay,
            str(r.before_onset),
            r.verdict,
            r.checked,
        ]
        for r in view.runs
    ]
    headers = ["kind", "bag", "onset", "first alarm", "detection", "delay", "early", "verdict"]
    headers.append("samples checked")
    lines += ["  " + line for line in table(headers, rows, "llrrrrrll")]
    if view.detection is not None:
        lines.append(view.detection.summary)
    return lines


def stability(view: Stability) -> str:
    """A stability report: per family each round's violated/total, the means and the ratio."""
    lines = [f"imrosc stability of {view.config}", view.summary, ""]
    headers = ["family", *(r.label for r in view.rounds)]
    headers += ["violated (mean)", "total (mean)", "ratio"]
    rows = [
        [row.family, *(c.text for c in row.cells), row.violated_mean, row.total_mean, row.ratio]
        for row in view.rows
    ]
    lines += table(headers, rows)
    lines.append("(per round: invariants violated by the held-out bags / invariants inferred)")
    if view.rounds:
        lines.append("")
    for r in view.rounds:
        lines.append(f"{r.label}: {r.summary}")
        lines += [f"  unreadable {e.bag}: {e.error}" if e.bag else f"  {e.error}" for e in r.errors]
    return "\n".join(lines) + "\n"
