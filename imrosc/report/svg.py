"""Chart geometry for the HTML reports: scales, ticks, path strings, downsampled series.

Everything a chart template draws is computed here and handed over spelled out: pixel
coordinates as short decimal strings, tick labels, path data. The templates
(``templates/charts.html.j2``) only place these values into SVG elements.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from imrosc.report.values import finite, number, percent, plural, seconds
from imrosc.report.views import Episode, Run, Stability

LIMIT = 2000
"""At most this many points of one series are drawn; longer series are downsampled."""

MAX_ROWS = 200
"""At most this many invariants get a row of a violation timeline."""

PALETTE = 8
"""Series colours (CSS classes ``s0`` to ``s7``) before they repeat."""

ROW, MARK = 18, 10
"""A timeline row's height and the height of its marks, in pixels."""

CHAR = 7.5
"""Pixels a character of an 11px label takes, at most (monospace)."""

Point = tuple[float, float]


def coordinate(value: float) -> str:
    """A pixel coordinate, to a hundredth of a pixel, without trailing zeros.

    >>> coordinate(12.0), coordinate(3.14159), coordinate(-0.001)
    ('12', '3.14', '0')
    """
    text = f"{value:.2f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def nice_step(span: float, count: int) -> float:
    """The tick step of 1, 2 or 5 times a power of ten nearest to ``count`` intervals.

    >>> nice_step(10, 5), nice_step(1, 5), nice_step(0.7, 5), nice_step(60, 6)
    (2.0, 0.2, 0.1, 10.0)
    """
    raw = span / max(count, 1)
    power = 10.0 ** math.floor(math.log10(raw))
    return min((f * power for f in (1.0, 2.0, 5.0, 10.0)), key=lambda s: abs(math.log(s / raw)))


def tick_label(tick: float, step: float) -> str:
    """A tick value with as many decimals as the step needs.

    >>> tick_label(0.30000000000000004, 0.1), tick_label(-0.0, 1.0), tick_label(2e6, 5e5)
    ('0.3', '0', '2000000')
    """
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    if abs(tick) >= 1e15 or (tick != 0 and abs(tick) < 1e-6 and decimals > 12):
        return number(tick, 4)
    text = f"{tick:.{decimals}f}"
    return "0" if text.strip("-0.") == "" else text


def padded(lo: float, hi: float, share: float = 0.04) -> tuple[float, float]:
    """``lo..hi`` widened by ``share`` of its width on both sides, so no point sits on the frame.

    >>> padded(0.0, 10.0)
    (-0.4, 10.4)
    """
    pad = (hi - lo) * share
    return lo - pad, hi + pad


def domain(values: Iterable[float]) -> tuple[float, float]:
    """The least and greatest finite value, widened when there is no width to them.

    >>> domain([3.0, 1.0, float("nan")]), domain([5.0]), domain([])
    ((1.0, 3.0), (4.5, 5.5), (0.0, 1.0))
    """
    numbers = [v for v in values if math.isfinite(v)]
    if not numbers:
        return 0.0, 1.0
    lo, hi = min(numbers), max(numbers)
    if hi - lo <= 1e-12 * max(abs(lo), abs(hi), 1.0):
        pad = abs(lo) * 0.1 if lo else 0.5
        return lo - pad, hi + pad
    return lo, hi


def ticks(
    lo: float, hi: float, count: int = 5, extend: bool = True
) -> tuple[float, float, list[float], float]:
    """Nice ticks over ``lo..hi``: the domain (to whole steps if ``extend``), ticks, step.

    >>> ticks(0.3, 9.6)
    (0.0, 10.0, [0.0, 2.0, 4.0, 6.0, 8.0, 10.0], 2.0)
    >>> ticks(0.0, 61.5, 6, extend=False)
    (0.0, 61.5, [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0], 10.0)
    """
    step = nice_step(hi - lo, count)
    first, last = math.floor(lo / step + 1e-9), math.ceil(hi / step - 1e-9)
    if extend:
        lo, hi = first * step, last * step
    else:
        first, last = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
    return lo, hi, [round(i * step, 12) for i in range(first, last + 1)], step


@dataclass(frozen=True)
class Scale:
    """Maps ``lo..hi`` onto the pixels ``start..stop``."""

    lo: float
    hi: float
    start: float
    stop: float

    def __call__(self, value: float) -> float:
        """The pixel of ``value``."""
        return self.start + (value - self.lo) / (self.hi - self.lo) * (self.stop - self.start)

    def at(self, value: float) -> str:
        """The pixel of ``value``, spelled."""
        return coordinate(self(value))


@dataclass(frozen=True)
class Frame:
    """An SVG's size and its plot area: ``x0..x1`` left to right, ``y0..y1`` top to bottom."""

    width: int
    height: int
    x0: int
    x1: int
    y0: int
    y1: int

    @property
    def viewbox(self) -> str:
        """The SVG ``viewBox``."""
        return f"0 0 {self.width} {self.height}"

    @property
    def plot_width(self) -> int:
        """The width of the plot area."""
        return self.x1 - self.x0

    @property
    def plot_height(self) -> int:
        """The height of the plot area."""
        return self.y1 - self.y0

    @property
    def right_label_x(self) -> str:
        """Where labels right of the plot area start."""
        return coordinate(self.x1 + 4)

    @property
    def left_label_x(self) -> str:
        """Where row labels left of the plot area end."""
        return coordinate(self.x0 - 8)

    @property
    def x_label_x(self) -> str:
        """Where the x axis label is centred."""
        return coordinate((self.x0 + self.x1) / 2)

    @property
    def x_label_y(self) -> str:
        """The baseline of the x axis label."""
        return coordinate(self.height - 8)

    @property
    def y_label_x(self) -> str:
        """The baseline of the (rotated) y axis label."""
        return "14"

    @property
    def y_label_y(self) -> str:
        """Where the y axis label is centred."""
        return coordinate((self.y0 + self.y1) / 2)

    @property
    def tick_x_y(self) -> str:
        """The baseline of the x axis tick labels."""
        return coordinate(self.y1 + 16)

    @property
    def tick_y_x(self) -> str:
        """Where the y axis tick labels end."""
        return coordinate(self.x0 - 6)

    @property
    def tick_end_y(self) -> str:
        """Where the x axis tick marks end, below the axis."""
        return coordinate(self.y1 + 4)

    @property
    def tick_end_x(self) -> str:
        """Where the y axis tick marks end, left of the axis."""
        return coordinate(self.x0 - 4)


@dataclass(frozen=True)
class Tick:
    """A tick: its pixel along the axis and its label."""

    at: str
    label: str


@dataclass(frozen=True)
class Axis:
    """An axis: its name and its ticks."""

    label: str
    ticks: list[Tick]


def axis(label: str, scale: Scale, values: Sequence[float], step: float) -> Axis:
    """An axis named ``label`` with a tick at each of ``values``."""
    return Axis(label=label, ticks=[Tick(scale.at(v), tick_label(v, step)) for v in values])


@dataclass(frozen=True)
class Dot:
    """A marker at ``cx, cy`` with a tooltip."""

    cx: str
    cy: str
    title: str


def thin(points: Sequence[Any], limit: int = LIMIT) -> list[Any]:
    """At most ``limit`` of ``points``, evenly spaced, the first and the last kept.

    >>> thin(list(range(10)), 4)
    [0, 3, 6, 9]
    """
    if len(points) <= limit:
        return list(points)
    if limit < 2:
        return list(points[:limit])
    last = len(points) - 1
    return [points[round(i * last / (limit - 1))] for i in range(limit)]


def envelope(points: Sequence[Point], limit: int = LIMIT) -> list[Point]:
    """At most ``limit`` of ``points`` (in order) keeping each stretch's lowest and highest.

    A line through these looks like the line through all of them: no spike is lost.

    >>> envelope([(0, 1), (1, 5), (2, 2), (3, 0), (4, 3), (5, 3)], 4)
    [(0, 1), (1, 5), (3, 0), (4, 3)]
    """
    if len(points) <= limit:
        return list(points)
    buckets = max(limit // 2, 1)
    kept: list[Point] = []
    for b in range(buckets):
        chunk = points[b * len(points) // buckets : (b + 1) * len(points) // buckets]
        if not chunk:
            continue
        low = min(range(len(chunk)), key=lambda i: chunk[i][1])
        high = max(range(len(chunk)), key=lambda i: chunk[i][1])
        kept += [chunk[i] for i in sorted({low, high})]
    return kept


def _pairs(rows: Any, pick: Callable[[Sequence[Any]], Sequence[Any]]) -> list[tuple[float, ...]]:
    """Rows of numbers, those with a non-finite or missing one left out."""
    kept = []
    for row in rows or []:
        if not isinstance(row, Sequence) or isinstance(row, str):
            continue
        try:
            picked = pick(row)
        except IndexError:
            continue
        if all(finite(v) for v in picked):
            kept.append(tuple(float(v) for v in picked))
    return kept


def _shown(drawn: int, total: int, what: str) -> str:
    return f"{what}: {drawn} of {total} points drawn" if drawn < total else ""


# ------------------------------------------------------------------------------ polygons


@dataclass(frozen=True)
class PolygonChart:
    """A two-variable polygon invariant: the polygon, the trajectory, offending points."""

    title: str
    text: str
    frame: Frame
    x: Axis
    y: Axis
    path: str
    vertices: int
    trajectory: str
    offending: list[Dot]
    notes: list[str]


def polygon_chart(plot: Mapping[str, Any], start: float) -> PolygonChart:
    """The scatter chart of a polygon plot of a run that started at ``start``."""
    frame = Frame(width=560, height=460, x0=72, x1=540, y0=16, y1=400)
    vertices = _pairs(plot.get("vertices"), lambda r: (r[0], r[1]))
    trajectory = _pairs(plot.get("trajectory"), lambda r: (r[0], r[1], r[2]))
    offending = _pairs(plot.get("offending"), lambda r: (r[0], r[1], r[2]))
    xs = [v[0] for v in vertices] + [p[1] for p in trajectory] + [p[1] for p in offending]
    ys = [v[1] for v in vertices] + [p[2] for p in trajectory] + [p[2] for p in offending]
    x_lo, x_hi, x_ticks, x_step = ticks(*padded(*domain(xs)), count=6)
    y_lo, y_hi, y_ticks, y_step = ticks(*padded(*domain(ys)), count=6)
    sx = Scale(x_lo, x_hi, frame.x0, frame.x1)
    sy = Scale(y_lo, y_hi, frame.y1, frame.y0)
    path = " ".join(
        f"{'M' if i == 0 else 'L'}{sx.at(x)},{sy.at(y)}" for i, (x, y) in enumerate(vertices)
    )
    drawn = thin(trajectory)
    shown = thin(offending)
    x_name, y_name = str(plot.get("x", "x")), str(plot.get("y", "y"))
    notes = [
        n
        for n in (
            _shown(len(drawn), len(trajectory), "trajectory"),
            _shown(len(shown), len(offending), "offending"),
        )
        if n
    ]
    return PolygonChart(
        title=f"{plot.get('invariant', '')} at {plot.get('point', '')}",
        text=str(plot.get("text", "")),
        frame=frame,
        x=axis(x_name, sx, x_ticks, x_step),
        y=axis(y_name, sy, y_ticks, y_step),
        path=path + (" Z" if path else ""),
        vertices=len(vertices),
        trajectory=" ".join(f"{sx.at(x)},{sy.at(y)}" for _, x, y in drawn),
        offending=[
            Dot(
                sx.at(x),
                sy.at(y),
                f"{seconds(t - start)}: {x_name} = {number(x)}, {y_name} = {number(y)}",
            )
            for t, x, y in shown
        ],
        notes=notes,
    )


# ---------------------------------------------------------------------------- frequencies


@dataclass(frozen=True)
class Bound:
    """A horizontal dashed line at a bound, labelled at its right end."""

    y: str
    label: str
    label_y: str


@dataclass(frozen=True)
class FrequencyChart:
    """A topic's rate over time against the invariant's bounds."""

    title: str
    frame: Frame
    x: Axis
    y: Axis
    line: str
    bounds: list[Bound]
    outside: list[Dot]
    notes: list[str]


def frequency_chart(plot: Mapping[str, Any], start: float, duration: float) -> FrequencyChart:
    """The line chart of a frequency plot of a run that started at ``start``."""
    frame = Frame(width=760, height=300, x0=64, x1=680, y0=14, y1=250)
    series = [(t - start, hz) for t, hz in _pairs(plot.get("series"), lambda r: (r[0], r[1]))]
    series.sort(key=lambda p: p[0])
    low = float(plot["min"]) if finite(plot.get("min")) else None
    high = float(plot["max"]) if finite(plot.get("max")) else None
    outside = [
        p for p in series if (low is not None and p[1] < low) or (high is not None and p[1] > high)
    ]
    times = [0.0, duration] + [t for t, _ in series]
    x_lo, x_hi, x_ticks, x_step = ticks(*domain(times), count=6, extend=False)
    rates = [hz for _, hz in series] + [b for b in (low, high) if b is not None] + [0.0]
    y_lo, y_hi, y_ticks, y_step = ticks(*domain(rates), count=5)
    sx = Scale(x_lo, x_hi, frame.x0, frame.x1)
    sy = Scale(y_lo, y_hi, frame.y1, frame.y0)
    line = envelope(series)
    shown = thin(outside)
    bounds = [
        Bound(sy.at(b), f"{name} {number(b)} Hz", coordinate(sy(b) + (12 if name == "min" else -4)))
        for name, b in (("min", low), ("max", high))
        if b is not None
    ]
    notes = [
        n
        for n in (
            _shown(len(line), len(series), "rate"),
            _shown(len(shown), len(outside), "out of bounds"),
        )
        if n
    ]
    return FrequencyChart(
        title=f"{plot.get('topic', '')}: {plot.get('invariant', '')} at {plot.get('point', '')}",
        frame=frame,
        x=axis("time (s)", sx, x_ticks, x_step),
        y=axis("rate (Hz)", sy, y_ticks, y_step),
        line=" ".join(f"{sx.at(t)},{sy.at(hz)}" for t, hz in line),
        bounds=bounds,
        outside=[Dot(sx.at(t), sy.at(hz), f"{seconds(t)}: {number(hz)} Hz") for t, hz in shown],
        notes=notes,
    )


# ------------------------------------------------------------------------------- timeline


@dataclass(frozen=True)
class Mark:
    """One episode (or several, too close to tell apart) on a timeline row."""

    x: str
    width: str
    title: str


@dataclass(frozen=True)
class Row:
    """A violated invariant's row of a timeline."""

    label: str
    title: str
    y: str
    label_y: str
    marks: list[Mark]


@dataclass(frozen=True)
class TimelineChart:
    """When each violated invariant of a run was violated."""

    frame: Frame
    x: Axis
    rows: list[Row]
    mark_height: str
    notes: list[str]


def _merge(episodes: Sequence[Episode], scale: Scale) -> list[Mark]:
    """Marks of ``episodes``, those less than a pixel apart merged into one."""
    spans: list[tuple[float, float, list[Episode]]] = []
    for e in sorted(episodes, key=lambda e: e.offset):
        x, end = scale(e.offset), max(scale(e.end_offset), scale(e.offset) + 2.0)
        if spans and x <= spans[-1][1] + 1.0:
            spans[-1] = (spans[-1][0], max(spans[-1][1], end), [*spans[-1][2], e])
        else:
            spans.append((x, end, [e]))
    marks = []
    for x, end, group in spans:
        if len(group) == 1:
            e = group[0]
            title = f"{e.time}: {e.comparison or e.text}"
            if e.repeat:
                title += f" {e.repeat}"
        else:
            until = max(group, key=lambda e: e.end_offset).until
            title = f"{plural(len(group), 'episode')} from {group[0].time} to {until}"
        marks.append(Mark(coordinate(x), coordinate(end - x), title))
    return marks


def timeline_chart(run: Run) -> TimelineChart:
    """The violation timeline of a run: one row per violated invariant, in order of violation."""
    rows_of: dict[str, list[Episode]] = {}
    for e in run.episodes:  # in time order: rows come in order of first violation
        rows_of.setdefault(e.invariant, []).append(e)
    notes = []
    if len(rows_of) > MAX_ROWS:
        notes.append(f"the first {MAX_ROWS} of {len(rows_of)} violated invariants shown")
    shown = list(rows_of.items())[:MAX_ROWS]
    labels = [(name, f"{name} {eps[0].family}".strip()) for name, eps in shown]
    widest = max((len(label) for _, label in labels), default=8)
    x0 = 16 + int(CHAR * min(widest, 32))
    width, height = max(x0 + 600, 900), 12 + ROW * len(shown) + 44
    frame = Frame(width=width, height=height, x0=x0, x1=width - 24, y0=12, y1=height - 44)
    times = [0.0, run.duration, *(t for e in run.episodes for t in (e.offset, e.end_offset))]
    lo, hi, values, step = ticks(*domain(times), count=8, extend=False)
    sx = Scale(lo, hi, frame.x0, frame.x1)
    rows = []
    for i, ((name, eps), (_, label)) in enumerate(zip(shown, labels, strict=True)):
        top = frame.y0 + ROW * i
        rows.append(
            Row(
                label=label if len(label) <= 32 else label[:31] + "\u2026",
                title=f"{name} at {eps[0].point}: {eps[0].text}",
                y=coordinate(top + (ROW - MARK) / 2),
                label_y=coordinate(top + ROW / 2 + 4),
                marks=_merge(eps, sx),
            )
        )
    return TimelineChart(
        frame=frame,
        x=axis("time (s)", sx, values, step),
        rows=rows,
        mark_height=str(MARK),
        notes=notes,
    )


# ----------------------------------------------------------------------------------- bars


@dataclass(frozen=True)
class Bar:
    """A bar: its rectangle, its colour class, its value label and its tooltip."""

    x: str
    y: str
    width: str
    height: str
    css: str
    title: str
    label: str = ""
    label_x: str = ""
    label_y: str = ""
    name: str = ""


@dataclass(frozen=True)
class SmallBars:
    """A few horizontal bars, each with its name left and its value right."""

    title: str
    width: int
    height: int
    name_x: str
    bars: list[Bar]

    @property
    def viewbox(self) -> str:
        """The SVG ``viewBox``."""
        return f"0 0 {self.width} {self.height}"


def small_bars(title: str, items: Sequence[tuple[str, int, str]], scale_to: int) -> SmallBars:
    """Bars of ``(name, count, css class)``, lengths relative to ``scale_to``."""
    width, left, right, height = 300, 64, 230, 14
    scale = Scale(0.0, float(max(scale_to, 1)), left, right)
    bars = []
    for i, (name, count, css) in enumerate(items):
        top = 4 + i * (height + 6)
        end = scale(min(max(count, 0), max(scale_to, 1)))
        bars.append(
            Bar(
                x=str(left),
                y=str(top),
                width=coordinate(max(end - left, 0.0)),
                height=str(height),
                css=css,
                title=f"{title}: {count} {name}",
                label=str(count),
                label_x=coordinate(end + 4),
                label_y=coordinate(top + height - 3),
                name=name,
            )
        )
    return SmallBars(
        title=title,
        width=width,
        height=8 + len(items) * (height + 6) - 6,
        name_x=str(left - 6),
        bars=bars,
    )


@dataclass(frozen=True)
class Swatch:
    """A legend entry."""

    x: str
    y: str
    label_x: str
    label_y: str
    css: str
    label: str


@dataclass(frozen=True)
class Group:
    """A group's name under its bars."""

    label: str
    x: str


@dataclass(frozen=True)
class GroupedBars:
    """Bars grouped by family, one per round, with a legend of rounds."""

    frame: Frame
    y: Axis
    groups: list[Group]
    bars: list[Bar]
    legend: list[Swatch]


def stability_chart(view: Stability) -> GroupedBars:
    """Per family, each round's share of violated invariants."""
    rounds = len(view.rounds)
    slot = 14 if rounds <= 8 else 8
    widest = max((len(row.family) for row in view.rows), default=0)
    group_width = max(max(rounds, 1) * slot + 24, int(CHAR * widest) + 12)
    x0 = 56
    width = max(x0 + group_width * len(view.rows) + 24, 420)
    legend_rows = math.ceil(rounds / 6) if rounds else 0
    frame = Frame(width=width, height=260 + 18 * legend_rows, x0=x0, x1=width - 16, y0=14, y1=214)
    shares = [c.share for row in view.rows for c in row.cells]
    top = max([s for s in shares if s is not None] + [0.0])
    lo, hi, values, step = ticks(0.0, max(top * 100.0, 1.0), count=5)
    sy = Scale(lo, hi, frame.y1, frame.y0)
    bars, groups = [], []
    for g, row in enumerate(view.rows):
        left = frame.x0 + 12 + g * group_width
        groups.append(Group(row.family, coordinate(left + rounds * slot / 2)))
        for r, cell in enumerate(row.cells):
            share = cell.share
            if share is None:
                continue
            y = min(sy(share * 100.0), frame.y1 - 1.0)  # a measured 0 shows as a sliver
            bars.append(
                Bar(
                    x=coordinate(left + r * slot + 1),
                    y=coordinate(y),
                    width=coordinate(slot - 2),
                    height=coordinate(frame.y1 - y),
                    css=f"s{r % PALETTE}",
                    title=(
                        f"{row.family}, {view.rounds[r].label}: {cell.text} violated "
                        f"({percent(share)})"
                    ),
                )
            )
    legend = []
    for r, round_ in enumerate(view.rounds):
        x = frame.x0 + (r % 6) * 90
        y = frame.y1 + 34 + (r // 6) * 18
        legend.append(
            Swatch(
                coordinate(x),
                coordinate(y - 9),
                coordinate(x + 14),
                coordinate(y),
                f"s{r % PALETTE}",
                round_.label,
            )
        )
    return GroupedBars(
        frame=frame,
        y=axis("violated (%)", sy, values, step),
        groups=groups,
        bars=bars,
        legend=legend,
    )
