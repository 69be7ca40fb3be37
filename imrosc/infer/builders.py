"""Which function builds the inference states of which family: registered against the
family catalog (:mod:`imrosc.runtime.families`).

A state module registers its family with :func:`builds` beside its state class::

    @builds(BOUNDS)
    def _bounds(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
        return [BoundsState(point.variables, one_of=ONE_OF in enabled)]

``enabled`` is every family the job enables at the point (a state may read its
neighbours': bounds leave a constant to one-of). :func:`point_states` calls the builders of
the families enabled at a point in catalog order; the family packages' modules are
imported first (:func:`load`), so a new state module in one of them needs no other edit.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterable

from imrosc.infer.core import FamilyState, Variable
from imrosc.ir import Tunables
from imrosc.runtime.families import ARCH, CALL, FAMILIES, NAMES, PARAM, PUBLISH, TEMPORAL
from imrosc.translate.points import PointSpec

__all__ = [
    "StateBuilder",
    "States",
    "builder",
    "builds",
    "load",
    "point_states",
    "registered",
    "variables_point",
]

States = list[FamilyState]
StateBuilder = Callable[[PointSpec, Tunables, frozenset[str]], States]

PACKAGES = ("imrosc.infer.daikon", "imrosc.infer.timed", "imrosc.infer.polygon")
"""The packages whose modules register value families' builders."""
EVENT_PACKAGES = ("imrosc.infer.arch", "imrosc.infer.temporal")
_BUILDERS: dict[str, StateBuilder] = {}
_LOADED: list[bool] = []


def builds(name: str) -> Callable[[StateBuilder], StateBuilder]:
    """Register the decorated function as the builder of the catalog's family ``name``."""
    family = FAMILIES.get(name)
    if family is None:
        raise ValueError(f"{name!r} is not in the family catalog (imrosc/runtime/families.py)")
    if not family.points:
        raise ValueError(f"{name!r} is learnt by classification, not inferred at a point")

    def register(function: StateBuilder) -> StateBuilder:
        if _BUILDERS.get(name, function) is not function:
            raise ValueError(f"{name!r} has a state builder already")
        _BUILDERS[name] = function
        return function

    return register


def load() -> None:
    """Import every module of the family packages (each registers its builders)."""
    if _LOADED:
        return
    for package_name in (*PACKAGES, *EVENT_PACKAGES):
        package = importlib.import_module(package_name)
        for module in pkgutil.iter_modules(package.__path__):
            importlib.import_module(f"{package_name}.{module.name}")
    _LOADED.append(True)


def builder(name: str) -> StateBuilder:
    """The registered builder of family ``name`` (``KeyError`` for none)."""
    load()
    return _BUILDERS[name]


def registered() -> frozenset[str]:
    """The families with a builder."""
    load()
    return frozenset(_BUILDERS)


_SAME_STATES = {ARCH: frozenset({ARCH}), TEMPORAL: frozenset({TEMPORAL})}
_VALUE_KINDS = frozenset({PUBLISH, CALL, PARAM})


def point_states(
    point: PointSpec, tunables: Tunables, names: Iterable[str] = NAMES
) -> list[FamilyState]:
    """Fresh states of the families of ``names`` that the job enables at ``point``, in
    catalog order: at an ``arch`` or ``temporal`` point the families of that kind, at the
    others (``publish``, ``call``, ``param``) those of any of these kinds."""
    load()
    enabled = frozenset(point.families)
    kinds = _SAME_STATES.get(point.kind, _VALUE_KINDS)
    wanted = set(names) & enabled
    states: list[FamilyState] = []
    for name in NAMES:
        if name in wanted and FAMILIES[name].points & kinds:
            states += _BUILDERS[name](point, tunables, enabled)
    return states


def variables_point(
    variables: Iterable[Variable], families: Iterable[str], kind: str = PUBLISH
) -> PointSpec:
    """A point of ``kind`` with ``variables`` enabling ``families`` (for a family package's
    ``make_states``, which knows the variables only)."""
    return PointSpec("", kind, tuple(variables), tuple(families))
