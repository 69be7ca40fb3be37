"""What the tests of ``imrosc record`` share: a small configuration and the one-line error
check."""

from __future__ import annotations

from click.testing import Result

CONFIG = """<imROS project="small robot">
  <scope>
    <publish id="a" relative="1">/cmd</publish>
    <call id="c">/task</call>
    <param id="p">/gain</param>
  </scope>
</imROS>
"""


def one_line_error(result: Result, status: int = 1) -> str:
    assert result.exit_code == status, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert "Traceback" not in result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    return lines[0]
