"""Architecture family (thesis 3.4.3): minimum and maximum publisher, subscriber, server sets."""

from imrosc.infer.arch.sets import (
    FAMILY,
    RESOURCE_KINDS,
    ArchitectureState,
    format_nodes,
    make_states,
    parse_variable,
)

__all__ = [
    "FAMILY",
    "RESOURCE_KINDS",
    "ArchitectureState",
    "format_nodes",
    "make_states",
    "parse_variable",
]
