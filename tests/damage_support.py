"""What the damage tests of the bag readers (ROS 1 and ROS 2) ask of every damaged bag."""

from __future__ import annotations

import contextlib
from pathlib import Path

from imrosc.bags import BagError, MessageError, open_bag, recovered


def reads_or_refuses_in_one_line(bag: Path) -> None:
    """``bag`` opens and every message it yields is read (a message that does not decode
    may raise the reader's own error), or it is refused by a :class:`BagError` of one line
    that quotes no bytes; a recovery is said in one line too."""
    try:
        with open_bag(bag) as reader:
            assert reader.message_count >= 0 and "\n" not in (recovered(reader) or "")
            for connection, _, raw in reader.messages():
                with contextlib.suppress(MessageError):
                    reader.deserialize(raw, connection.msgtype)
    except BagError as error:
        assert "\n" not in error.message and "\\x" not in error.message
