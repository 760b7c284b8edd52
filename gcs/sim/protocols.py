"""The request/answer services of a mock vehicle beside commands and setpoints, routed by
message type: parameters (`gcs.sim.params`), missions, fences and rally points
(`gcs.sim.missions`), TIMESYNC, MANUAL_CONTROL and MAVFTP.

TIMESYNC as PX4's `MavlinkTimesync`: a request (tc1 = 0) is answered with tc1 = the vehicle's
own clock in ns and ts1 echoed; an answer (tc1 != 0) to the mock's own requests is not used.
MANUAL_CONTROL addressed to the vehicle is manual control input: Position mode is refused
without it (`gcs.sim.commands`). MAVFTP (FILE_TRANSFER_PROTOCOL): the mock has no files, so
every request is answered NAK FileNotFound (session resets ACKed), the answer PX4 gives for a
missing file; a ground station asking for a file (MAVProxy's parameter file) falls back at
once instead of timing out.
"""

from __future__ import annotations

from typing import Any, Protocol

from gcs.sim.config import MockFaults
from gcs.sim.messages import ENCODER
from gcs.sim.missions import VehicleMissions
from gcs.sim.params import VehicleParams

__all__ = ["HANDLED", "ServiceHost", "ftp_answer", "handle"]

_PARAMS = frozenset({"PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"})
_MISSIONS = frozenset({"MISSION_REQUEST_LIST", "MISSION_REQUEST_INT", "MISSION_REQUEST",
                       "MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK",
                       "MISSION_CLEAR_ALL"})
#: Message types `handle` takes.
HANDLED = _PARAMS | _MISSIONS | {"TIMESYNC", "MANUAL_CONTROL", "FILE_TRANSFER_PROTOCOL"}

#: MAVFTP opcodes and error codes used (MAVLink's FTP protocol).
_FTP_TERMINATE_SESSION, _FTP_RESET_SESSIONS = 1, 2
_FTP_ACK, _FTP_NAK = 128, 129
_FTP_FILE_NOT_FOUND = 10


class ServiceHost(Protocol):
    """What these services need of a vehicle (`gcs.sim.vehicle.MockVehicle` has it)."""

    system_id: int
    params: VehicleParams
    missions: VehicleMissions
    last_manual_control: float
    faults: MockFaults

    def now(self) -> float: ...
    def reply(self, msg: Any) -> None: ...


def handle(v: ServiceHost, msg: Any) -> None:
    """Handle one message of a type in `HANDLED`."""
    kind = msg.get_type()
    if kind in _PARAMS:
        if not v.faults.params_silent:
            v.params.handle(msg)
    elif kind in _MISSIONS:
        v.missions.handle(msg)
    elif kind == "TIMESYNC":
        if msg.tc1 == 0:
            v.reply(ENCODER.timesync_encode(int(v.now() * 1e9), msg.ts1))
    elif kind == "MANUAL_CONTROL" and msg.target == v.system_id:
        v.last_manual_control = v.now()
    elif kind == "FILE_TRANSFER_PROTOCOL" and msg.target_system == v.system_id:
        v.reply(ftp_answer(bytes(msg.payload), msg.get_srcSystem(), msg.get_srcComponent()))


def ftp_answer(request: bytes, system: int, component: int) -> Any:
    """The FILE_TRANSFER_PROTOCOL answer to `request` (a MAVFTP payload) from a vehicle
    without files: ACK for session resets, NAK FileNotFound for everything else."""
    seq = int.from_bytes(request[0:2], "little")
    session, opcode = request[2], request[3]
    if opcode in (_FTP_TERMINATE_SESSION, _FTP_RESET_SESSIONS):
        head = bytes([session, _FTP_ACK, 0, opcode, 0, 0])
    else:
        head = bytes([session, _FTP_NAK, 1, opcode, 0, 0])
    payload = ((seq + 1) & 0xFFFF).to_bytes(2, "little") + head + bytes(4)
    if opcode not in (_FTP_TERMINATE_SESSION, _FTP_RESET_SESSIONS):
        payload += bytes([_FTP_FILE_NOT_FOUND])
    return ENCODER.file_transfer_protocol_encode(0, system, component,
                                                 list(payload.ljust(251, b"\0")))
