"""What every pass may use besides the IR: the ROS graph and a place to report diagnostics."""

from __future__ import annotations

from dataclasses import dataclass, field

from imrosc import ir
from imrosc.diagnostics import Diagnostic, make
from imrosc.graph.model import Graph


@dataclass
class PassContext:
    """The graph (if any source gave one) and the diagnostics the passes report."""

    path: str = "<config>"
    graph: Graph | None = None
    diagnostics: list[Diagnostic] = field(default_factory=list)

    def report(self, span: ir.Span, code: str, message: str) -> None:
        """Report a diagnostic at ``span`` of the configuration."""
        self.diagnostics.append(make(self.path, span.line, span.column, code, message))
