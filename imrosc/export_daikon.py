"""``imrosc export-daikon``: the translated program points as Daikon 5 ``.decls``/``.dtrace``.

One Daikon program point per imrosc program point (``<key>:::POINT``), one ``.dtrace`` per
bag, as the thesis' translator produced for Daikon (section 3.3). Numbers are ``double``,
strings and architecture sets ``java.lang.String``; a missing value is written as
``nonsensical`` with modified flag 2, as Daikon's format asks. Each file carries imrosc's
generated-file mark as a ``//`` comment line (Daikon skips them); files without it are
overwritten only with ``--force``.
"""

from __future__ import annotations

import io
import math
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, BinaryIO, TextIO

from imrosc.infer.core import Samples, Variable
from imrosc.outputs import DAIKON, mark, target, write_atomic
from imrosc.progress import Progress
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


def write_decls(stream: TextIO, specs: Iterable[PointSpec], banner: str = "") -> None:
    """The declarations of every point (Daikon's decl-version 2.0; ``banner``: comment lines
    after the header)."""
    stream.write(f"decl-version 2.0\nvar-comparability none\n{banner}\n")
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


DECLS = "imrosc.decls"


def targets(
    out: Path, bags: Sequence[Path], *, force: bool = False, inputs: Iterable[Path] = ()
) -> list[Path]:
    """``<out>/imrosc.decls`` and one ``<out>/<NNN>-<bag>.dtrace`` per bag (sorted), each
    checked before anything is written (:func:`imrosc.outputs.target`: the user's own files
    are overwritten only with ``force``)."""
    inputs = tuple(inputs)
    names = [DECLS] + [f"{run:03d}-{bag.name}.dtrace" for run, bag in enumerate(sorted(bags))]
    return [target(out / name, DAIKON, inputs=inputs, force=force) for name in names]


def export(
    specs: Sequence[PointSpec],
    layouts: Any,
    callerids: Any,
    bags: Sequence[Path],
    paths: Sequence[Path],
    progress: Progress | None = None,
) -> list[Path]:
    """Write the declarations to ``paths[0]`` and each bag's samples (bags sorted) to the
    next paths (:func:`targets`), each atomically; return the files. ``progress`` hears of
    each bag done."""
    banner = f"// {mark(DAIKON)} (imrosc export-daikon)\n"

    def decls(binary: BinaryIO) -> None:
        stream = io.TextIOWrapper(binary, encoding="utf-8")
        write_decls(stream, specs, banner)
        stream.flush()
        stream.detach()  # the binary stream stays open for write_atomic

    write_atomic(paths[0], decls)
    for run, (bag, path) in enumerate(zip(sorted(bags), paths[1:], strict=True)):

        def trace(binary: BinaryIO, bag: Path = bag, run: int = run) -> None:
            translator = BagTranslator(specs, layouts, callerids)
            stream = io.TextIOWrapper(binary, encoding="utf-8")
            stream.write(banner + "\n")
            for samples in translator.translate(bag, run):
                write_samples(stream, samples)
            stream.flush()
            stream.detach()
            if progress is not None:
                progress(bag, translator.messages)

        write_atomic(path, trace)
    return list(paths)
