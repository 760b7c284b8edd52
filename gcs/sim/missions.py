"""The mission protocol on a mock vehicle, for missions, geofences and rally points
(mission_type 0, 1, 2), as PX4's `MavlinkMissionManager` runs it.

Upload: MISSION_COUNT (0 clears the list and is ACKed at once), then the vehicle requests each
item with MISSION_REQUEST_INT, re-requesting after `RETRY_S` without an answer and giving up
after `TIMEOUT_S` without progress ("Operation timeout"), and ends with MISSION_ACK ACCEPTED.
An item out of order is re-requested; one of the wrong kind for its list (a fence list takes
only fence vertices and circles, a rally list only rally points) or with an invalid vertex
count or radius ends the transfer with the MISSION_ACK error PX4 gives. Download:
MISSION_REQUEST_LIST is answered with MISSION_COUNT (0 when empty), then each MISSION_REQUEST_INT
(or the older MISSION_REQUEST) with the item, until the GCS's MISSION_ACK. MISSION_CLEAR_ALL
clears one list, or all with MAV_MISSION_TYPE_ALL. One transfer at a time per vehicle: another
MISSION_COUNT meanwhile is refused (MAV_MISSION_DENIED), as PX4 refuses a busy manager.

The stored lists (`VehicleMissions.items`) are kept as received (MISSION_ITEM_INT fields);
`fence` gives the geofence as vertex polygons and circles for breach checks.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from gcs.autopilot import px4
from gcs.wire import addressed_to, mavlink

__all__ = ["MAX_ITEMS", "RETRY_S", "TIMEOUT_S", "FenceShape", "MissionHost", "MissionItem",
           "VehicleMissions"]

_m = mavlink
#: Re-request an item after this long without it (PX4: MAVLINK_MISSION_RETRY_TIMEOUT_DEFAULT).
RETRY_S = 0.25
#: Give a transfer up after this long without progress
#: (PX4: MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT).
TIMEOUT_S = px4.MISSION_PROTOCOL_TIMEOUT_S
#: Most items a list takes (PX4's dataman holds far more; a bound on the mock's memory).
MAX_ITEMS = 2000

MISSION, FENCE, RALLY = (_m.MAV_MISSION_TYPE_MISSION, _m.MAV_MISSION_TYPE_FENCE,
                         _m.MAV_MISSION_TYPE_RALLY)
_TYPES = (MISSION, FENCE, RALLY)
_POLYGON = (_m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            _m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION)
_CIRCLE = (_m.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, _m.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION)
_FENCE_COMMANDS = (*_POLYGON, *_CIRCLE, _m.MAV_CMD_NAV_FENCE_RETURN_POINT)


@dataclass(frozen=True)
class MissionItem:
    """One stored item, with MISSION_ITEM_INT's fields (x, y: degE7 for global frames)."""

    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float


@dataclass(frozen=True)
class FenceShape:
    """A geofence polygon (vertices) or circle (one centre and a radius), lat/lon degrees."""

    inclusion: bool
    vertices: tuple[tuple[float, float], ...]
    radius: float | None = None
    """Metres for a circle; None for a polygon."""


class MissionHost(Protocol):
    """What the mission protocol needs of a vehicle (`gcs.sim.vehicle.MockVehicle`)."""

    system_id: int
    component_id: int

    def now(self) -> float: ...
    def reply(self, msg: Any) -> None: ...
    def replier(self) -> Callable[[Any], None]: ...
    def statustext(self, severity: int, text: str) -> None: ...


@dataclass
class _Upload:
    mission_type: int
    count: int
    partner: tuple[int, int]
    reply: Callable[[Any], None]
    items: list[MissionItem]
    last_sent: float
    last_progress: float


class VehicleMissions:
    """One vehicle's stored mission, fence and rally lists and its side of the protocol."""

    def __init__(self, host: MissionHost) -> None:
        self.host = host
        self.items: dict[int, list[MissionItem]] = {t: [] for t in _TYPES}
        """Stored lists by mission_type (0 mission, 1 fence, 2 rally)."""
        self._upload: _Upload | None = None
        self.changed: Callable[[int], None] | None = None
        """Called with the mission_type whenever a list is replaced or cleared."""

    @property
    def fence(self) -> list[FenceShape]:
        """The stored geofence as shapes (polygons from runs of vertices)."""
        shapes: list[FenceShape] = []
        items = self.items[FENCE]
        k = 0
        while k < len(items):
            item = items[k]
            lat_lon = (item.x * 1e-7, item.y * 1e-7)
            if item.command in _CIRCLE:
                shapes.append(FenceShape(item.command == _CIRCLE[0], (lat_lon,), item.param1))
                k += 1
            elif item.command in _POLYGON:
                n = int(item.param1)
                run = items[k:k + n]
                shapes.append(FenceShape(item.command == _POLYGON[0],
                                         tuple((i.x * 1e-7, i.y * 1e-7) for i in run)))
                k += max(n, 1)
            else:
                k += 1
        return shapes

    # ---------------------------------------------------------------- protocol

    def handle(self, msg: Any) -> None:
        """A mission-protocol message addressed to this vehicle."""
        host = self.host
        if not addressed_to(msg, host.system_id, host.component_id):
            return
        kind = msg.get_type()
        mission_type = getattr(msg, "mission_type", MISSION)
        if kind == "MISSION_CLEAR_ALL":
            self._clear(msg, mission_type)
        elif mission_type not in _TYPES:
            self._ack(msg, _m.MAV_MISSION_UNSUPPORTED, mission_type)
        elif kind == "MISSION_REQUEST_LIST":
            host.reply(_m.MAVLink_mission_count_message(
                msg.get_srcSystem(), msg.get_srcComponent(), len(self.items[mission_type]),
                mission_type))
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            self._send_item(msg, mission_type, as_int=kind == "MISSION_REQUEST_INT")
        elif kind == "MISSION_COUNT":
            self._start_upload(msg, mission_type)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            self._take_item(msg, mission_type)
        # MISSION_ACK from the GCS closes a download: nothing is kept for it

    def tick(self, now: float) -> None:
        """Retries and the timeout of an upload in progress (called every mock tick)."""
        up = self._upload
        if up is None:
            return
        if now - up.last_progress > TIMEOUT_S:
            self._upload = None
            self.host.statustext(_m.MAV_SEVERITY_CRITICAL, "Operation timeout")
        elif now - up.last_sent > RETRY_S:
            self._request(up, now)

    # ------------------------------------------------------------------ steps

    def _ack(self, msg: Any, result: int, mission_type: int) -> None:
        self.host.reply(_m.MAVLink_mission_ack_message(
            msg.get_srcSystem(), msg.get_srcComponent(), result, mission_type))

    def _clear(self, msg: Any, mission_type: int) -> None:
        if mission_type == _m.MAV_MISSION_TYPE_ALL:
            cleared = list(_TYPES)
        elif mission_type in _TYPES:
            cleared = [mission_type]
        else:
            self._ack(msg, _m.MAV_MISSION_UNSUPPORTED, mission_type)
            return
        if self._upload is not None and self._upload.mission_type in cleared:
            self._upload = None
        for t in cleared:
            self._store(t, [])
        self._ack(msg, _m.MAV_MISSION_ACCEPTED, mission_type)

    def _store(self, mission_type: int, items: list[MissionItem]) -> None:
        self.items[mission_type] = items
        if self.changed is not None:
            self.changed(mission_type)

    def _send_item(self, msg: Any, mission_type: int, as_int: bool) -> None:
        items = self.items[mission_type]
        if not 0 <= msg.seq < len(items):
            self._ack(msg, _m.MAV_MISSION_INVALID_SEQUENCE, mission_type)
            return
        i = items[msg.seq]
        src, comp = msg.get_srcSystem(), msg.get_srcComponent()
        if as_int:
            out = _m.MAVLink_mission_item_int_message(
                src, comp, i.seq, i.frame, i.command, i.current, i.autocontinue, i.param1,
                i.param2, i.param3, i.param4, i.x, i.y, i.z, mission_type)
        else:
            out = _m.MAVLink_mission_item_message(
                src, comp, i.seq, i.frame, i.command, i.current, i.autocontinue, i.param1,
                i.param2, i.param3, i.param4, i.x * 1e-7, i.y * 1e-7, i.z, mission_type)
        self.host.reply(out)

    def _start_upload(self, msg: Any, mission_type: int) -> None:
        up = self._upload
        partner = (msg.get_srcSystem(), msg.get_srcComponent())
        if up is not None and not (up.partner == partner and up.mission_type == mission_type
                                   and not up.items):
            self._ack(msg, _m.MAV_MISSION_DENIED, mission_type)
            return
        if msg.count > MAX_ITEMS:
            self._ack(msg, _m.MAV_MISSION_NO_SPACE, mission_type)
            return
        if msg.count == 0:
            self._upload = None
            self._store(mission_type, [])
            self._ack(msg, _m.MAV_MISSION_ACCEPTED, mission_type)
            return
        now = self.host.now()
        self._upload = _Upload(mission_type, msg.count, partner, self.host.replier(), [], now,
                               now)
        self._request(self._upload, now)

    def _request(self, up: _Upload, now: float) -> None:
        up.last_sent = now
        up.reply(_m.MAVLink_mission_request_int_message(
            up.partner[0], up.partner[1], len(up.items), up.mission_type))

    def _take_item(self, msg: Any, mission_type: int) -> None:
        up = self._upload
        if up is None or up.mission_type != mission_type:
            return  # not uploading this list: PX4 ignores it
        now = self.host.now()
        if msg.seq != len(up.items):  # a duplicate or a gap: ask again for the one we need
            self._request(up, now)
            return
        item = _item(msg)
        error = _item_error(mission_type, item)
        if error is not None:
            self._upload = None
            self._ack(msg, error, mission_type)
            return
        up.items.append(item)
        up.last_progress = now
        if len(up.items) < up.count:
            self._request(up, now)
            return
        self._upload = None
        self._store(mission_type, up.items)
        self._ack(msg, _m.MAV_MISSION_ACCEPTED, mission_type)


def _item(msg: Any) -> MissionItem:
    """A received MISSION_ITEM_INT or MISSION_ITEM as stored (x, y in degE7)."""
    x, y = msg.x, msg.y
    if msg.get_type() == "MISSION_ITEM" and msg.frame not in (
            _m.MAV_FRAME_LOCAL_NED, _m.MAV_FRAME_LOCAL_ENU, _m.MAV_FRAME_MISSION):
        x, y = round(x * 1e7), round(y * 1e7)
    return MissionItem(msg.seq, msg.frame, msg.command, msg.current, msg.autocontinue,
                       msg.param1, msg.param2, msg.param3, msg.param4, int(x), int(y), msg.z)


def _item_error(mission_type: int, item: MissionItem) -> int | None:
    """The MISSION_ACK error PX4 gives for `item` in a list of `mission_type`, or None."""
    if mission_type == FENCE:
        if item.command not in _FENCE_COMMANDS:
            return int(_m.MAV_MISSION_UNSUPPORTED)
        if item.command in _POLYGON and item.param1 < 3:
            return int(_m.MAV_MISSION_INVALID_PARAM1)
        if item.command in _CIRCLE and not item.param1 > 0:
            return int(_m.MAV_MISSION_INVALID_PARAM1)
    elif mission_type == RALLY:
        if item.command != _m.MAV_CMD_NAV_RALLY_POINT:
            return int(_m.MAV_MISSION_UNSUPPORTED)
    elif item.command in (*_FENCE_COMMANDS, _m.MAV_CMD_NAV_RALLY_POINT):
        return int(_m.MAV_MISSION_UNSUPPORTED)
    return None
