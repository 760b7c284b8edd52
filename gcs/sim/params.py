"""The parameter protocol on a mock vehicle, as PX4's `MavlinkParametersManager` runs it.

PARAM_REQUEST_LIST streams PX4's ``_HASH_CHECK`` value (index -1, for a GCS's cache) and then
every parameter as PARAM_VALUE with its index and the count, a few per mock tick (PX4 sends
five per cycle on UDP). PARAM_REQUEST_READ answers one parameter, by name (index -1) or by
index; an unknown one gets PX4's ``[pm] unknown param`` STATUSTEXT. PARAM_SET answers with the
new PARAM_VALUE on every link; an unknown name (``[pm] unknown param: NAME``) or a type other
than the parameter's own (``[pm] param types mismatch param: NAME``) is refused with PX4's
STATUSTEXT and no PARAM_VALUE. PX4 stores values outside a parameter's documented range
(ranges are metadata for ground stations); the mock refuses them, and non-finite ones, with a
STATUSTEXT and the unchanged PARAM_VALUE, because it could not model them.

Values travel as PX4 sends them: REAL32 as the float, INT32 byte-wise in the float field
(MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE). A parameter the mock models writes its
`MockConfig` field (`MODELLED`) or its row of the model's speed limits (`MODEL_LIMITS`), so
PARAM_SET changes that vehicle's behaviour at once.
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Callable
from typing import Any, Protocol

from gcs.sim.arducopter_params import ARDUCOPTER_PARAMS
from gcs.sim.config import MockConfig, MockFaults
from gcs.sim.model import FleetModel
from gcs.sim.paramdefs import PX4_PARAMS, ParamDef
from gcs.wire import PARAM_TYPES, addressed_to, decode_param, encode_param, mavlink

__all__ = ["HASH_PARAM", "MODELLED", "MODEL_LIMITS", "PARAMS_PER_TICK", "ParamHost",
           "VehicleParams", "decode_value", "encode_value"]

#: The pseudo-parameter PX4 sends first in a list (its value: a hash of all values).
HASH_PARAM = "_HASH_CHECK"
#: PARAM_VALUEs of a list sent per mock tick (PX4: five per MAVLink cycle on UDP).
PARAMS_PER_TICK = 5
#: Parameters that change the mock's behaviour: name -> the `MockConfig` field it writes.
MODELLED: dict[str, str] = {
    "COM_OF_LOSS_T": "offboard_loss_timeout",
    "COM_FAIL_ACT_T": "failsafe_action_delay",
    "COM_OBL_RC_ACT": "offboard_loss_action",
    "COM_DISARM_LAND": "disarm_after_land",
    "COM_DISARM_PRFLT": "disarm_preflight",
    "MPC_LAND_SPEED": "land_speed",
    "MIS_TAKEOFF_ALT": "takeoff_altitude",
    "RTL_RETURN_ALT": "rtl_return_altitude",
    "GF_ACTION": "geofence_action",
    "COM_RC_LOSS_T": "manual_control_timeout",
}
#: Parameters that set the vehicle's row of a `FleetModel` speed-limit array.
MODEL_LIMITS: dict[str, str] = {
    "MPC_XY_VEL_MAX": "velocity_xy_max",
    "MPC_Z_VEL_MAX_UP": "velocity_up_max",
    "MPC_Z_VEL_MAX_DN": "velocity_down_max",
}

_m = mavlink
_TYPES = PARAM_TYPES


encode_value = encode_param
decode_value = decode_param


class ParamHost(Protocol):
    """What the parameter protocol needs of a vehicle (`gcs.sim.vehicle.MockVehicle`)."""

    system_id: int
    component_id: int
    index: int

    faults: MockFaults

    @property
    def config(self) -> MockConfig: ...
    @property
    def model(self) -> FleetModel: ...
    def send(self, msg: Any) -> None: ...
    def reply(self, msg: Any) -> None: ...
    def replier(self) -> Callable[[Any], None]: ...
    def statustext(self, severity: int, text: str) -> None: ...


class VehicleParams:
    """One vehicle's parameters (PX4's defaults, its own MAV_SYS_ID, the modelled ones read
    from its `MockConfig`) and its side of the parameter protocol."""

    def __init__(self, host: ParamHost) -> None:
        self.host = host
        ardupilot = host.config.autopilot == "ardupilot"
        self.table = ARDUCOPTER_PARAMS if ardupilot else PX4_PARAMS
        """Its parameter set: PX4's, or ArduCopter's (`MockConfig.autopilot`)."""
        self.values: dict[str, float] = {name: d.default for name, d in self.table.items()}
        self.values["MAV_SYSID" if ardupilot else "MAV_SYS_ID"] = float(host.system_id)
        for name, field in MODELLED.items():
            if name in self.table:
                self.values[name] = float(getattr(host.config, field))
        for name, field in MODEL_LIMITS.items():
            if name in self.table:
                self.values[name] = float(getattr(host.model, field)[host.index])
        self.names = list(self.table)
        """Parameter names by index (PX4's order: sorted by name)."""
        self._index = {name: i for i, name in enumerate(self.names)}
        self._queue: list[int] = []
        self._reply: Callable[[Any], None] = host.send

    def __len__(self) -> int:
        return len(self.names)

    def value(self, name: str) -> float:
        """The value of `name` (KeyError if PX4 has no such parameter here)."""
        return self.values[name]

    # ---------------------------------------------------------------- protocol

    def handle(self, msg: Any) -> None:
        """PARAM_REQUEST_LIST, PARAM_REQUEST_READ or PARAM_SET addressed to this vehicle."""
        host = self.host
        if not addressed_to(msg, host.system_id, host.component_id):
            return
        kind = msg.get_type()
        if kind == "PARAM_REQUEST_LIST":
            self._reply = host.replier()
            self._queue = [-1, *range(len(self.names))]
        elif kind == "PARAM_REQUEST_READ":
            self._read(msg)
        elif kind == "PARAM_SET":
            self._set(msg)

    def drain(self) -> None:
        """Send the next PARAMS_PER_TICK values of a list in progress (called every tick)."""
        for _ in range(min(PARAMS_PER_TICK, len(self._queue))):
            index = self._queue.pop(0)
            self._reply(self._hash_message() if index < 0 else self.message(index))

    def message(self, index: int) -> Any:
        """PARAM_VALUE of the parameter at `index`."""
        name = self.names[index]
        d = self.table[name]
        return _m.MAVLink_param_value_message(
            name.encode(), encode_value(d.kind, self.values[name]), _TYPES[d.kind],
            len(self.names), index)

    def _hash_message(self) -> Any:
        digest = zlib.crc32(repr(sorted(self.values.items())).encode())
        field = struct.unpack("<f", struct.pack("<I", digest))[0]
        return _m.MAVLink_param_value_message(HASH_PARAM.encode(), field,
                                              _m.MAV_PARAM_TYPE_UINT32, len(self.names), 65535)

    def _read(self, msg: Any) -> None:
        host = self.host
        if msg.param_index >= 0:
            if msg.param_index >= len(self.names):
                host.statustext(_m.MAV_SEVERITY_INFO, f"[pm] unknown param ID: {msg.param_index}")
                return
            host.reply(self.message(msg.param_index))
            return
        name = _name(msg.param_id)
        if name == HASH_PARAM:
            host.reply(self._hash_message())
        elif name in self._index:
            host.reply(self.message(self._index[name]))
        else:
            host.statustext(_m.MAV_SEVERITY_INFO, f"[pm] unknown param: {name}")

    def _set(self, msg: Any) -> None:
        host = self.host
        name = _name(msg.param_id)
        if name == HASH_PARAM:  # PX4: the GCS has the list cached; stop sending it
            self._queue.clear()
            return
        d = self.table.get(name)
        if d is None:
            host.statustext(_m.MAV_SEVERITY_INFO, f"[pm] unknown param: {name}")
            return
        if msg.param_type != _TYPES[d.kind]:
            host.statustext(_m.MAV_SEVERITY_ERROR, f"[pm] param types mismatch param: {name}")
            return
        value = decode_value(d.kind, msg.param_value)
        problem = _range_problem(d, value)
        if name in host.faults.params_kept:
            host.reply(self.message(self._index[name]))
        elif problem is None:
            self.values[name] = value
            if name in MODELLED:
                setattr(host.config, MODELLED[name], value)
            elif name in MODEL_LIMITS:
                getattr(host.model, MODEL_LIMITS[name])[host.index] = value
            host.send(self.message(self._index[name]))  # PX4 broadcasts the new value
        else:
            host.statustext(_m.MAV_SEVERITY_WARNING, f"[pm] {name}: {problem}")
            host.reply(self.message(self._index[name]))


def _name(param_id: Any) -> str:
    """A param_id field as text (pymavlink gives str; NUL padding removed)."""
    text = param_id.decode(errors="replace") if isinstance(param_id, bytes) else str(param_id)
    return text.split("\x00", 1)[0]


def _range_problem(d: ParamDef, value: float) -> str | None:
    if not math.isfinite(value):
        return "value not finite"
    if not d.low <= value <= d.high:
        return f"{value:g} out of range [{d.low:g}, {d.high:g}]"
    return None
