"""A small deterministic simulation of the thesis' landing system that writes bags.

The UAV landing on a moving platform of section 5.1 (Figure 3.6): an AscTec Hummingbird takes
off, hovers, pursues an iRobot Create wandering in an 8 m x 8 m Vicon room and lands on its
platform; the controller's state machine goes startup, launch, hover, task, land, shutdown
(0 to 5). Runs are seeded and deterministic: the same seed writes the same bytes.

>>> run = simulate(7, duration=5.0)
>>> [s.topic for s in run.streams][:3]
['/vicon/car', '/a/car_pose', '/a/subject_pose']
>>> len(run.stream("/a/car_pose"))
100

:func:`write_run` writes one run as a ROS 1 bag or a ROS 2 bag (sqlite3 or MCAP),
:func:`write_runs` many; a :class:`Scenario` injects one of the faults of
:mod:`imrosc.sim.scenarios`.
"""

from imrosc.sim.bags import FORMATS, BagFormat, Run, simulate, write_run, write_runs
from imrosc.sim.recording import GRAPH, TOPICS, Stream, TopicSpec
from imrosc.sim.scenarios import FAMILIES, SCENARIO_KINDS, Scenario, ScenarioKind
from imrosc.sim.world import STATES, World

__all__ = [
    "FAMILIES",
    "FORMATS",
    "GRAPH",
    "SCENARIO_KINDS",
    "STATES",
    "TOPICS",
    "BagFormat",
    "Run",
    "Scenario",
    "ScenarioKind",
    "Stream",
    "TopicSpec",
    "World",
    "simulate",
    "write_run",
    "write_runs",
]
