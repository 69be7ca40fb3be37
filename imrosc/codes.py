"""The registry of diagnostic codes: one stable kebab-case code per kind of problem.

Codes never change meaning once released; ``docs/diagnostics.md`` lists every code here
(a test keeps the two in step) and ``tests/fixtures/check/`` holds one fixture per code.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass


class Severity(str, enum.Enum):
    """How bad a diagnostic is: errors fail ``imrosc check``; warnings only with ``--strict``;
    notes only inform."""

    ERROR = "error"
    WARNING = "warning"
    NOTE = "note"


@dataclass(frozen=True)
class Code:
    """One diagnostic code: its name, default severity, the stage that emits it and a summary."""

    name: str
    severity: Severity
    stage: str
    summary: str


_E = Severity.ERROR
_W = Severity.WARNING
_N = Severity.NOTE

CODES: tuple[Code, ...] = (
    # Reading the file.
    Code("io-error", _E, "read", "The file cannot be read (missing, a directory, no permission)."),
    Code("file-too-large", _E, "read", "The file is larger than the configuration size cap."),
    Code("encoding-error", _E, "read", "The file is not UTF-8, or declares another encoding."),
    Code("xml-syntax", _E, "parse", "The file is not well-formed XML."),
    Code(
        "dtd-forbidden",
        _E,
        "parse",
        "The document has a DOCTYPE; DTDs and entities are refused (XXE, billion laughs).",
    ),
    # Structure, checked against grammar/imros.xsd.
    Code("unknown-root", _E, "schema", "The root element is not <imROS>."),
    Code("unexpected-element", _E, "schema", "An element that the grammar does not allow here."),
    Code("missing-element", _E, "schema", "A required child element is missing."),
    Code("unknown-attribute", _E, "schema", "An attribute that the element does not have."),
    Code("missing-attribute", _E, "schema", "A required attribute is missing."),
    Code("invalid-value", _E, "schema", "An attribute or text value is not of its type."),
    # Semantics the XSD cannot express.
    Code("duplicate-id", _E, "semantic", "Two elements share one id."),
    Code(
        "bad-id",
        _E,
        "semantic",
        "An id breaks its lexical rule: scope elements and actions take lowercase letters, "
        "conditions take digits.",
    ),
    Code("unknown-ref", _E, "semantic", "An id in events, conds or <violation> names nothing."),
    Code("wrong-ref-kind", _E, "semantic", "An id names an element of the wrong kind."),
    Code("bad-violation", _E, "semantic", "A <violation> is not of the form POINTS -> ACTIONS."),
    Code("bad-name", _E, "semantic", "A topic, service or parameter name is not a ROS name."),
    Code(
        "relative-name",
        _W,
        "semantic",
        "A name is not global; it is resolved against the root namespace.",
    ),
    Code(
        "ros2-incompatible-name",
        _W,
        "semantic",
        "A valid ROS 1 name that ROS 2 rejects (a token starting with a digit, or '__').",
    ),
    Code("missing-topic", _E, "semantic", "A point or condition names no topic or service."),
    Code(
        "topic-conflict",
        _E,
        "semantic",
        "A name is given both as text and as child elements.",
    ),
    Code("bad-relative", _E, "semantic", "The relative hop count is negative."),
    Code(
        "unknown-family",
        _E,
        "semantic",
        "A families attribute names no invariant family or group a publish point has.",
    ),
    Code("bad-pattern", _E, "semantic", "A temporal pattern is not a valid regular expression."),
    Code(
        "pattern-unknown-event",
        _E,
        "semantic",
        "A lowercase letter in a pattern is not an event of its <temporal>.",
    ),
    Code(
        "pattern-too-few-events",
        _E,
        "semantic",
        "A pattern has more placeholders than its <temporal> has events to bind them to.",
    ),
    Code("bad-expression", _E, "semantic", "A condition <value> is not a valid expression."),
    Code(
        "constant-condition",
        _E,
        "semantic",
        "A condition <value> reads no field or topic: it holds always or never.",
    ),
    Code(
        "foreign-topic-operand",
        _E,
        "semantic",
        "A condition <value> names another topic than the condition's <topic> as an operand.",
    ),
    Code(
        "window-below-resolution",
        _E,
        "semantic",
        "The <detect> window is shorter than the resolution of the bags' timestamps (1 us).",
    ),
    Code("bad-action-value", _E, "semantic", "An action <value> is not a YAML flow mapping."),
    Code("bad-arch-kind", _E, "semantic", "An <arch> kind is not one of pub, sub, srv."),
    Code(
        "monitor-without-invariants",
        _E,
        "semantic",
        "A <monitor> has no invariants file: no inv on it, on <check> or on <detect>.",
    ),
    Code("check-mixed", _E, "semantic", "A <check> holds both <success>/<fail> and <bag>."),
    Code(
        "check-incomplete",
        _E,
        "semantic",
        "A <check> has <success> without <fail> or the reverse, or no bags at all.",
    ),
    Code(
        "onset-conflict",
        _E,
        "semantic",
        "A <fail> gives its fault's onset more than one way (onset, onset_topic, onsets).",
    ),
    Code(
        "threshold-unused",
        _W,
        "semantic",
        'A <check> gives a threshold, which only select="fscore" uses.',
    ),
    Code("unused-condition", _W, "semantic", "A condition that no point uses."),
    Code(
        "uninvolved-event",
        _W,
        "semantic",
        "An event that no ordered pair or pattern of its <temporal> can involve.",
    ),
    Code("unused-action", _W, "semantic", "An action that no <violation> takes."),
    Code(
        "unmonitored-block",
        _W,
        "semantic",
        "A blocked topic or service that no <publish> or <call> point monitors.",
    ),
    # Graph files and bags (imrosc graph, imrosc build).
    Code("graph-syntax", _E, "graph", "A graph file is not valid YAML."),
    Code("graph-invalid", _E, "graph", "A graph file does not follow the graph file format."),
    Code("bag-error", _E, "graph", "A bag cannot be opened or read; it is skipped."),
    Code(
        "bag-recovered",
        _W,
        "graph",
        "A bag cut short, never indexed or without its metadata.yaml; its messages up to "
        "the last whole record are read.",
    ),
    Code(
        "bag-empty",
        _W,
        "translate",
        "A bag has no message on the configured topics; it adds no samples.",
    ),
    Code(
        "bag-type-drift",
        _W,
        "translate",
        "A topic has another message type here than in an earlier bag; fields match by name.",
    ),
    # The check stage (imrosc classify).
    Code(
        "onset-unusable",
        _W,
        "classify",
        "A <fail> run's onset cannot be used (past the bag's end, a label topic missing or "
        "never non-zero, a bag the onsets file does not list); the run is scored whole.",
    ),
    Code(
        "success-in-detect",
        _W,
        "classify",
        "A <success> bag is also a <detect> bag: it cannot violate what was learnt from it, so "
        "false positives are 0 by construction.",
    ),
    Code(
        "cross-validation-unneeded",
        _W,
        "classify",
        "--cross-validate asked, but no <success> bag is a <detect> bag: nothing to "
        "cross-validate; the runs are scored as without it.",
    ),
    Code(
        "no-monitor-kept",
        _W,
        "classify",
        "No candidate monitor is worth more than none on the held-out failed runs (or none "
        "by more than a standard error); the refined file keeps no invariants.",
    ),
    # Lowering (imrosc build).
    Code(
        "relative-without-graph",
        _E,
        "lower",
        "relative > 0 but no graph source says who subscribes to what.",
    ),
    Code(
        "unknown-topic",
        _E,
        "lower",
        "Relative grouping needs the publisher of a topic the graph does not know.",
    ),
    Code(
        "relative-cycle",
        _N,
        "lower",
        "Relative grouping went round a cycle of the graph; each topic is grouped once.",
    ),
    # Monitor backends (imrosc build --backend ros1).
    Code("monitor-missing", _E, "backend", "A monitor backend needs a <monitor> in the config."),
    Code(
        "invariants-unreadable",
        _E,
        "backend",
        "The monitor's invariants file is missing, unreadable or not an imrosc invariants file.",
    ),
    Code(
        "project-mismatch",
        _W,
        "backend",
        "The invariants file was inferred for another project than the configuration's.",
    ),
    Code(
        "bad-field-path",
        _E,
        "backend",
        "A variable's field path is not a chain of Python identifiers (with one [index]).",
    ),
    Code("bad-type-name", _E, "backend", "A message type name is not pkg/Type or pkg/msg/Type."),
    Code(
        "bad-package-name",
        _E,
        "backend",
        "The project name does not give a valid ROS package name (<project>_monitor).",
    ),
    Code(
        "action-type-unknown",
        _N,
        "backend",
        "No invariants file or bag knows an action topic's type; the node asks the master.",
    ),
    Code(
        "launch-error",
        _E,
        "backend",
        "The <monitor> launch file is not a roslaunch XML file (unreadable: io-error).",
    ),
    Code(
        "launch-without-graph",
        _E,
        "backend",
        "Blocked topics need a graph that knows subscribers to rewrite the launch file.",
    ),
    Code(
        "launch-unknown-node",
        _W,
        "backend",
        "A node of the launch file that the graph does not know; it is not remapped.",
    ),
    Code(
        "launch-unrewritten",
        _W,
        "backend",
        "A part of the launch file imrosc cannot rewrite safely (an include, a scope remap).",
    ),
)

BY_NAME: dict[str, Code] = {code.name: code for code in CODES}


def lookup(name: str) -> Code:
    """Return the registered code called ``name``; unknown names are a programming error."""
    return BY_NAME[name]
