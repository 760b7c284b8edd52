"""What a mock vehicle says in STATUSTEXT, as PX4 says it: a long text in MAVLink 2 chunks
(never cut mid-word), the same text not repeated within `STATUSTEXT_REPEAT_S`."""

from __future__ import annotations

import itertools
import math
from typing import Any

from gcs.sim.messages import ENCODER

__all__ = ["STATUSTEXT_LEN", "STATUSTEXT_REPEAT_S", "StatusTextOut", "statustext_chunks"]

#: STATUSTEXT carries at most 50 bytes of text per message.
STATUSTEXT_LEN = 50
#: The same STATUSTEXT is not sent again within this many seconds.
STATUSTEXT_REPEAT_S = 3.0

#: Ids of chunked texts, counting across every vehicle of the process.
_text_ids = itertools.count(1)


def statustext_chunks(text: str) -> list[str]:
    """`text` in pieces of at most `STATUSTEXT_LEN` bytes whose concatenation is `text`, each
    cut just after a space where there is one (MAVLink 2 STATUSTEXT chunking). With several
    pieces the last is shorter than the limit, so its NUL padding marks the end."""
    data = text.encode()
    if len(data) <= STATUSTEXT_LEN:
        return [text]
    chunks: list[str] = []
    rest = data
    while len(rest) >= STATUSTEXT_LEN:
        space = rest.rfind(b" ", 0, STATUSTEXT_LEN)
        cut = space + 1 if space > 0 else STATUSTEXT_LEN - 1
        chunks.append(rest[:cut].decode(errors="replace"))
        rest = rest[cut:]
    chunks.append(rest.decode(errors="replace"))
    return chunks


class StatusTextOut:
    """One vehicle's STATUSTEXT output: the texts it said (`said`, in order) and the messages
    of a new one; a text said in the last `STATUSTEXT_REPEAT_S` seconds is not said again
    (a GCS retrying arming gets it once, like PX4's rate-limited health reports)."""

    def __init__(self) -> None:
        self.said: list[str] = []
        self._last: dict[str, float] = {}

    def messages(self, severity: int, text: str, now: float) -> list[Any]:
        """The STATUSTEXT messages saying `text` at mock time `now` (none if it is a repeat)."""
        if now - self._last.get(text, -math.inf) < STATUSTEXT_REPEAT_S:
            return []
        self._last[text] = now
        self.said.append(text)
        chunks = statustext_chunks(text)
        text_id = 0 if len(chunks) == 1 else next(_text_ids) % 65535 + 1
        return [ENCODER.statustext_encode(severity, chunk.encode(), text_id, seq)
                for seq, chunk in enumerate(chunks)]
