"""A third-party backend: one text file naming the project's program points."""

from __future__ import annotations

from imrosc.backends.registry import BuildInputs, register


@register("toy")
def render(inputs: BuildInputs) -> dict[str, bytes]:
    points = ", ".join(sorted(str(p.id) for p in inputs.project.points))
    return {"points.txt": f"{inputs.banner('toy')}\n{points}\n".encode()}
