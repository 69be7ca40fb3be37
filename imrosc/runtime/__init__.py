"""The runtime engine: one implementation of every invariant check.

Replay, classification, comparison, stability and the generated monitor nodes all feed
this engine. It depends on numpy and the standard library only and keeps Python 3.8
syntax, so a ROS Noetic robot runs it unchanged from the monitor package that carries it.

Feed it what happens, in time order: :meth:`Engine.message` (a topic's flattened
message), :meth:`Engine.call` (a service call), :meth:`Engine.params` (parameter values),
:meth:`Engine.graph` (a snapshot of publishers, subscribers and servers) and
:meth:`Engine.advance` (the clock moved: timers); each returns the
:class:`Violation` s it found.
"""

from .engine import Engine
from .violation import Violation

__all__ = ["Engine", "Violation"]
