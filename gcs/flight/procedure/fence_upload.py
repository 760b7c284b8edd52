"""The geofence's way onto a vehicle: the mission protocol with mission_type FENCE, then the
parameters its autopilot needs to act on it (`Autopilot.fence_enable`: ArduPilot's
FENCE_ENABLE; PX4 checks an uploaded fence by itself).

Upload: MISSION_COUNT, then each MISSION_REQUEST_INT (or MISSION_REQUEST) answered with its
MISSION_ITEM_INT (frame MAV_FRAME_GLOBAL, x/y degE7), until MISSION_ACK; nothing heard for
`ITEM_TIMEOUT_S` resends what was last sent, at most `RETRIES` times in a row (after the last
item, an ACK that never comes is left to the read-back: lost on the way, or the item was).
Read-back:
MISSION_REQUEST_LIST, MISSION_COUNT, each item asked for by MISSION_REQUEST_INT, then our
MISSION_ACK. `send_fence` does both and compares item by item (`gcs.geofence.item_mismatch`);
any failure is `GeofenceFailed` naming the vehicle, which refuses the flight before arming.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Sequence
from typing import Any

from gcs.autopilot import Autopilot
from gcs.errors import GeofenceFailed
from gcs.flight.link.interface import Link
from gcs.flight.procedure.params import ParamError, set_param
from gcs.geofence import FenceItem, item_mismatch
from gcs.wire import mavlink

__all__ = ["ITEM_TIMEOUT_S", "RETRIES", "download_fence", "enable_fence", "send_fence",
           "upload_fence"]

_m = mavlink
FENCE = _m.MAV_MISSION_TYPE_FENCE
#: Resend the last message after this long without an answer (s).
ITEM_TIMEOUT_S = 1.0
#: Resends in a row before the transfer is given up.
RETRIES = 4
_KINDS = frozenset({"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK", "MISSION_COUNT",
                    "MISSION_ITEM_INT"})


class _Inbox:
    """The vehicle's mission-protocol messages about its FENCE list, queued while in use."""

    def __init__(self, link: Link) -> None:
        self.queue: asyncio.Queue[Any] = asyncio.Queue()
        self._listening = link.listening(self._on)

    def _on(self, msg: Any, _now: float) -> None:
        if msg.get_type() in _KINDS and getattr(msg, "mission_type", 0) == FENCE:
            self.queue.put_nowait(msg)

    def __enter__(self) -> _Inbox:
        self._listening.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._listening.__exit__(*exc)

    async def next(self, deadline: float) -> Any | None:
        """The next message, or None at `deadline` (monotonic)."""
        try:
            return await asyncio.wait_for(self.queue.get(), max(0.0, deadline - time.monotonic()))
        except TimeoutError:
            return None


def _ack_name(result: int) -> str:
    entry = _m.enums["MAV_MISSION_RESULT"].get(result)
    return entry.name if entry is not None else str(result)


async def upload_fence(link: Link, items: Sequence[FenceItem]) -> None:
    """Upload `items` as the vehicle's FENCE list (`GeofenceFailed` unless ACCEPTED)."""
    mav, sysid, comp = link.mav, link.system_id, link.component_id
    last = mav.mission_count_encode(sysid, comp, len(items), FENCE)
    tries = 0
    with _Inbox(link) as inbox:
        link.send(last)
        deadline = time.monotonic() + ITEM_TIMEOUT_S
        while True:
            msg = await inbox.next(deadline)
            if msg is None:
                tries += 1
                if tries > RETRIES and last.get_type() == "MISSION_ITEM_INT" \
                        and last.seq == len(items) - 1:
                    return  # every item went; the ACK did not come: the read-back tells
                if tries > RETRIES:
                    raise GeofenceFailed(link.vehicle_id, f"upload: no answer after "
                                         f"{RETRIES + 1} tries of {last.get_type()}")
                link.send(last)
                deadline = time.monotonic() + ITEM_TIMEOUT_S
                continue
            kind = msg.get_type()
            if kind == "MISSION_ACK":
                if msg.type != _m.MAV_MISSION_ACCEPTED:
                    raise GeofenceFailed(link.vehicle_id, f"upload refused: MISSION_ACK "
                                                          f"{_ack_name(msg.type)}")
                if last.get_type() == "MISSION_ITEM_INT" and last.seq == len(items) - 1:
                    return
                raise GeofenceFailed(link.vehicle_id, "upload: MISSION_ACK ACCEPTED before "
                                                      "every item was sent")
            if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
                if not 0 <= msg.seq < len(items):
                    raise GeofenceFailed(link.vehicle_id, f"upload: item {msg.seq} requested "
                                                          f"of {len(items)}")
                i = items[msg.seq]
                last = mav.mission_item_int_encode(
                    sysid, comp, msg.seq, _m.MAV_FRAME_GLOBAL, i.command, 0, 1, i.param1, 0.0,
                    0.0, 0.0, i.x, i.y, 0.0, FENCE)
                link.send(last)
                tries = 0
                deadline = time.monotonic() + ITEM_TIMEOUT_S


async def download_fence(link: Link) -> list[FenceItem]:
    """Read the vehicle's FENCE list back (`GeofenceFailed` when it does not answer)."""
    mav, sysid, comp = link.mav, link.system_id, link.component_id
    with _Inbox(link) as inbox:
        count = await _ask(link, inbox, mav.mission_request_list_encode(sysid, comp, FENCE),
                           "MISSION_COUNT", None)
        items = []
        for seq in range(count.count):
            msg = await _ask(link, inbox, mav.mission_request_int_encode(sysid, comp, seq, FENCE),
                             "MISSION_ITEM_INT", seq)
            items.append(FenceItem(msg.command, float(msg.param1), int(msg.x), int(msg.y)))
        link.send(mav.mission_ack_encode(sysid, comp, _m.MAV_MISSION_ACCEPTED, FENCE))
    return items


async def _ask(link: Link, inbox: _Inbox, request: Any, kind: str,
               seq: int | None) -> Any:
    """Send `request` until a `kind` answer (with `seq`, when given) comes."""
    for _ in range(RETRIES + 1):
        link.send(request)
        deadline = time.monotonic() + ITEM_TIMEOUT_S
        while (msg := await inbox.next(deadline)) is not None:
            if msg.get_type() == "MISSION_ACK" and msg.type != _m.MAV_MISSION_ACCEPTED:
                raise GeofenceFailed(link.vehicle_id, f"read-back refused: MISSION_ACK "
                                                      f"{_ack_name(msg.type)}")
            if msg.get_type() == kind and (seq is None or msg.seq == seq):
                return msg
    raise GeofenceFailed(link.vehicle_id, f"read-back: no {kind} after {RETRIES + 1} tries "
                                          f"of {request.get_type()}")


async def send_fence(link: Link, items: Sequence[FenceItem]) -> None:
    """Upload `items`, read them back and compare (`GeofenceFailed` on any difference)."""
    await upload_fence(link, items)
    got = await download_fence(link)
    problem = item_mismatch(items, got)
    if problem is not None:
        raise GeofenceFailed(link.vehicle_id, f"read back different: {problem}")


async def enable_fence(link: Link, kind: Autopilot) -> str:
    """Set the parameters that make `kind` act on its uploaded fence; what was set, in words
    ("" when none is needed; `GeofenceFailed` when one is not taken)."""
    done = []
    for name, (param_kind, value) in kind.fence_enable.items():
        try:
            await set_param(link, name, param_kind, value)
        except ParamError as exc:
            raise GeofenceFailed(link.vehicle_id, f"uploaded, but not enabled: {exc}") from None
        done.append(f"{name} {value:g}")
    return ", ".join(done)
