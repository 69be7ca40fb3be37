"""``imrosc export-daikon``: the translated program points as Daikon 5 ``.decls``/``.dtrace``.

One Daikon program point per imrosc program point (``<key>:::POINT``), one ``.dtrace`` per
bag, as the thesis' translator produced for Daikon (section 3.3). Numbers are ``double``,
strings and architecture sets ``java.lang.String``; a missing value is written as
``nonsensical`` with modified flag 2, as Daikon's format asks.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, TextIO

from imrosc.infer.core import Samples, Variable
from imrosc.translate.points import PointSpec
from imrosc.translate.stream import BagTranslator

_UNSAFE = re.compile(r"[^A-Za-z0-9_./\[\]()?=-]")


def ppt_name(key: str) -> str:
    """The Daikon program point of an imrosc point key.

    >>> ppt_name("a?state==4")
    'a?state==4:::POINT'
    """
    return _UNSAFE.sub("_", key) + ":::POINT"


def _rep_type(variable: Variable) -> str:
    return "double" if variable.numeric else "java.lang.String"


def write_decls(stream: TextIO, specs: Iterable[PointSpec]) -> None:
    """The declarations of every point (Daikon's decl-version 2.0)."""
    stream.write("decl-version 2.0\nvar-comparability none\n\n")
    for spec in specs:
        stream.write(f"ppt {ppt_name(spec.key)}\nppt-type point\n")
        for variable in (Variable("time", "float"), *spec.variables):
            rep = _rep_type(variable)
            stream.write(
                f"variable {_UNSAFE.sub('_', variable.name)}\n  var-kind variable\n"
                f"  rep-type {rep}\n  dec-type {rep}\n"
            )
        stream.write("\n")


def _value(value: Any) -> tuple[str, int]:
    if value is None:  # an architecture resource the snapshot cannot tell yet
        return "nonsensical", 2
    if isinstance(value, frozenset):
        value = ",".join(sorted(value))
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
        return f'"{escaped}"', 1
    number = float(value)
    if math.isnan(number):
        return "nonsensical", 2
    if math.isinf(number):
        return ("Infinity" if number > 0 else "-Infinity"), 1
    return repr(number), 1


def write_samples(stream: TextIO, samples: Samples) -> None:
    """One Daikon sample record per row."""
    name = ppt_name(samples.point)
    columns = [(Variable("time", "float"), samples.time)]
    columns += [(v, samples.column(v.name)) for v in samples.variables]
    for row in range(len(samples)):
        stream.write(name + "\n")
        for variable, column in columns:
            text, modified = _value(column[row])
            stream.write(f"{_UNSAFE.sub('_', variable.name)}\n{text}\n{modified}\n")
        stream.write("\n")


def export(
    specs: Sequence[PointSpec],
    layouts: Any,
    callerids: Any,
    bags: Sequence[Path],
    out: Path,
) -> list[Path]:
    """Write ``<out>/imrosc.decls`` and one ``<bag>.dtrace`` per bag; return the files."""
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "imrosc.decls"]
    with open(written[0], "w", encoding="utf-8") as stream:
        write_decls(stream, specs)
    for run, bag in enumerate(sorted(bags)):
        target = out / f"{run:03d}-{bag.name}.dtrace"
        translator = BagTranslator(specs, layouts, callerids)
        with open(target, "w", encoding="utf-8") as stream:
            for samples in translator.translate(bag, run):
                write_samples(stream, samples)
        written.append(target)
    return written
