"""How numbers, times and observed values read in reports: one spelling for text and HTML."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

UNDEFINED = "-"
"""What an undefined value (a null precision, a ratio of nothing) reads as."""


def number(value: float, digits: int = 6) -> str:
    """A number, short: integers as integers, floats with ``digits`` significant digits.

    >>> number(4.1), number(19.0), number(1700000012.3), number(0.1 + 0.2), number(-0.0)
    ('4.1', '19', '1700000012.3', '0.3', '0')
    >>> number(float("nan")), number(float("-inf")), number(1e-7), number(3)
    ('nan', '-inf', '1e-07', '3')
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    text = f"{value:.{digits}g}"
    if "e" in text and 1e-4 <= abs(value) < 1e15:
        text = f"{value:.{digits}f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def value(item: Any) -> str:
    """An observed or expected value as found in a document: number, string, list, null.

    >>> value(4.1), value("nan"), value([1, 2.5, "x"]), value(None), value(True)
    ('4.1', 'nan', '[1, 2.5, x]', '-', 'true')
    """
    if item is None:
        return UNDEFINED
    if isinstance(item, str):
        return item
    if isinstance(item, (bool, int, float)):
        return number(item)
    if isinstance(item, Mapping):
        return "{" + ", ".join(f"{k}: {value(v)}" for k, v in item.items()) + "}"
    if isinstance(item, Sequence):
        return "[" + ", ".join(value(v) for v in item) + "]"
    return json.dumps(item, default=str)


def seconds(offset: float) -> str:
    """A time relative to the start of a run, in milliseconds' precision.

    >>> seconds(12.3), seconds(0), seconds(-0.0001)
    ('12.300 s', '0.000 s', '0.000 s')
    """
    if not math.isfinite(offset):
        return f"{number(offset)} s"
    text = f"{offset:.3f}"
    return f"{'0.000' if text == '-0.000' else text} s"


def fraction(score: float | None) -> str:
    """A score between 0 and 1 (precision, recall, F) with three decimals, or undefined.

    >>> fraction(0.857142), fraction(None), fraction(1)
    ('0.857', '-', '1.000')
    """
    if score is None or not math.isfinite(score):
        return UNDEFINED
    return f"{score:.3f}"


def percent(part: float | None, whole: float | None = 1.0) -> str:
    """``part / whole`` as a percentage with one decimal, or undefined when ``whole`` is 0.

    >>> percent(1, 8), percent(0.0625), percent(3, 0), percent(None)
    ('12.5%', '6.2%', '-', '-')
    """
    if part is None or whole is None or whole == 0:
        return UNDEFINED
    share = 100.0 * part / whole
    return f"{share:.1f}%" if math.isfinite(share) else UNDEFINED


def plural(count: int, word: str, words: str | None = None) -> str:
    """``count`` and ``word``, the plural past one.

    >>> plural(1, "run"), plural(2, "run"), plural(0, "episode"), plural(3, "is", "are")
    ('1 run', '2 runs', '0 episodes', '3 are')
    """
    return f"{count} {word if count == 1 else (words or word + 's')}"


def finite(item: Any) -> bool:
    """Whether ``item`` is a finite number (not a bool, not a string such as "nan")."""
    return isinstance(item, (int, float)) and not isinstance(item, bool) and math.isfinite(item)
