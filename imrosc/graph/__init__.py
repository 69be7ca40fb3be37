"""The node graph of a ROS system: who publishes, subscribes to and serves what.

* :mod:`imrosc.graph.model` holds the graph;
* :mod:`imrosc.graph.file` loads the user's graph file, through :mod:`imrosc.graph.yamltree`,
  a safe plain-YAML reader;
* :mod:`imrosc.graph.bags` reads the graph out of bags;
* :mod:`imrosc.graph.command` is ``imrosc graph``.

``docs/graph.md`` describes the sources and the file format.
"""

from __future__ import annotations

from imrosc.graph.file import load_graph_file
from imrosc.graph.model import Graph, Node

__all__ = ["Graph", "Node", "load_graph_file"]
