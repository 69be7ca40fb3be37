"""numpy's C entry points where its Python wrappers cost more than the work.

``np.count_nonzero`` is a Python function around ``multiarray.count_nonzero``: on the
small boolean arrays of a check the wrapper is two thirds of the cost. The module moved
(``numpy.core`` in numpy 1, ``numpy._core`` in numpy 2); if neither has it, the public
function it is.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable

import numpy as np


def _count_nonzero() -> Callable[[Any], int]:
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        found = getattr(module, "count_nonzero", None)
        if callable(found):
            return found  # type: ignore[no-any-return]
    return np.count_nonzero


count_nonzero = _count_nonzero()
"""How many elements of an array are not zero (``np.count_nonzero`` of one array)."""
