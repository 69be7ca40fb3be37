"""Helpers for calibration tests: learn the invariants of one float topic from bags."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from imrosc.detect import run_detect


def learn_scalar(
    folder: Path, bags: list[Path], name: str = "c", detect: str = ""
) -> dict[str, Any]:
    """The invariants document ``imrosc infer`` learns from ``bags`` for the one point ``a``
    on ``/a/x`` (written as ``name.xml``, ``name.inv``), ``detect`` the ``<detect>``
    element's further attributes."""
    listed = "".join(f"<bag>{b.name}</bag>" for b in bags)
    path = folder / f"{name}.xml"
    path.write_text(
        f'<imROS project="c"><scope><publish id="a">/a/x</publish></scope>'
        f'<detect inv="{name}.inv"{detect}>{listed}</detect></imROS>'
    )
    result = run_detect(path, workers=1)
    assert result.document is not None
    return result.document
