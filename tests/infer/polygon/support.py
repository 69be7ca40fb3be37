"""What the polygon tests share: a state fed columns in chunks, as a bag's are."""

from __future__ import annotations

import numpy as np

from imrosc.infer.core import FloatArray, Samples, Variable
from imrosc.infer.polygon import PolygonState


def state_of(columns: dict[str, FloatArray], kinds: dict[str, str], chunk: int) -> PolygonState:
    """A polygon state of ``columns`` (each variable a float unless ``kinds`` says
    otherwise), fed ``chunk`` rows at a time, each folded as it comes (no batching: the
    tests fold many small chunks)."""
    names = list(columns)
    variables = tuple(Variable(n, kinds.get(n, "float")) for n in names)  # type: ignore[arg-type]
    state = PolygonState(variables, batch=0)
    rows = len(columns[names[0]])
    for first in range(0, rows, chunk):
        stop = min(first + chunk, rows)
        part = {n: columns[n][first:stop] for n in names}
        state.update(Samples("p", 0, np.arange(first, stop, dtype=float), part, variables))
    return state
