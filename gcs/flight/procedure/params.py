"""The parameter protocol on one vehicle's link: read a parameter, set one and read back what
the vehicle keeps (PARAM_REQUEST_READ / PARAM_SET answered by PARAM_VALUE), for the link-loss
failsafe (`gcs.flight.procedure.failsafe`) and the fence (`gcs.flight.procedure.fence_upload`).
A parameter's kind ("f" or "i") says how its value travels (`gcs.wire.encode_param`); the
autopilot's tables give each parameter's kind.
"""

from __future__ import annotations

import asyncio
import math
import time
from typing import Any

from gcs.flight.link.interface import Link
from gcs.wire import PARAM_TYPES, decode_param, encode_param

__all__ = ["ANSWER_S", "TRIES", "ParamError", "read_param", "set_param"]

#: Tries of one parameter read or write, and the wait for each answer (s; a late answer to
#: an earlier try still counts). A flight is refused when its failsafe cannot be read or set,
#: so a lossy link must not cost it one: at 20 % loss each way a try fails with probability
#: 0.36, all ten with 4e-5 (three failed one of a fleet's ~16 exchanges about half the time).
TRIES = 10
ANSWER_S = 0.5


class ParamError(Exception):
    """A parameter was not answered or not taken (the reason in words)."""


async def _exchange(link: Link, name: str, send: Any) -> Any:
    """Send `send()`'s message until a PARAM_VALUE for `name` answers; that message."""
    answers: asyncio.Queue[Any] = asyncio.Queue()

    def on_message(msg: Any, _now: float) -> None:
        if msg.get_type() == "PARAM_VALUE" and _param_id(msg) == name:
            answers.put_nowait(msg)

    with link.listening(on_message):
        for _ in range(TRIES):
            link.send(send())
            deadline = time.monotonic() + ANSWER_S
            while (left := deadline - time.monotonic()) > 0:
                try:
                    return await asyncio.wait_for(answers.get(), left)
                except TimeoutError:
                    break
    raise ParamError(f"{name} not answered after {TRIES} tries")


def _param_id(msg: Any) -> str:
    raw = msg.param_id
    text = raw.decode(errors="replace") if isinstance(raw, bytes) else str(raw)
    return text.rstrip("\x00")


async def read_param(link: Link, name: str, kind: str) -> float:
    """The vehicle's value of parameter `name` (type `kind`: "f" or "i")."""
    msg = await _exchange(link, name, lambda: link.mav.param_request_read_encode(
        link.system_id, link.component_id, name.encode(), -1))
    return decode_param(kind, msg.param_value)


async def set_param(link: Link, name: str, kind: str, value: float) -> float:
    """Set parameter `name` to `value`; the value the vehicle answers with (`ParamError`
    when it keeps another)."""
    msg = await _exchange(link, name, lambda: link.mav.param_set_encode(
        link.system_id, link.component_id, name.encode(), encode_param(kind, value),
        PARAM_TYPES[kind]))
    got = decode_param(kind, msg.param_value)
    if not math.isclose(got, value, rel_tol=1e-6, abs_tol=1e-6):
        raise ParamError(f"{name} set to {value:g} but the vehicle keeps {got:g}")
    return got
