"""The request/answer services of a mock vehicle beside commands and setpoints, routed by
message type: parameters (`gcs.sim.params`), missions, fences and rally points
(`gcs.sim.missions`), TIMESYNC and MANUAL_CONTROL.

TIMESYNC as PX4's `MavlinkTimesync`: a request (tc1 = 0) is answered with tc1 = the vehicle's
own clock in ns and ts1 echoed; an answer (tc1 != 0) to the mock's own requests is not used.
MANUAL_CONTROL addressed to the vehicle is manual control input: Position mode is refused
without it (`gcs.sim.commands`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from gcs.sim.messages import ENCODER

if TYPE_CHECKING:
    from gcs.sim.vehicle import MockVehicle

__all__ = ["HANDLED", "handle"]

_PARAMS = frozenset({"PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"})
_MISSIONS = frozenset({"MISSION_REQUEST_LIST", "MISSION_REQUEST_INT", "MISSION_REQUEST",
                       "MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK",
                       "MISSION_CLEAR_ALL"})
#: Message types `handle` takes.
HANDLED = _PARAMS | _MISSIONS | {"TIMESYNC", "MANUAL_CONTROL"}


def handle(v: MockVehicle, msg: Any) -> None:
    """Handle one message of a type in `HANDLED`."""
    kind = msg.get_type()
    if kind in _PARAMS:
        v.params.handle(msg)
    elif kind in _MISSIONS:
        v.missions.handle(msg)
    elif kind == "TIMESYNC":
        if msg.tc1 == 0:
            v.reply(ENCODER.timesync_encode(int(v.now() * 1e9), msg.ts1))
    elif kind == "MANUAL_CONTROL" and msg.target == v.system_id:
        v.last_manual_control = v.now()
