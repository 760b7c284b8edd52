"""The mock's ArduCopter parameter set, as data: ArduCopter 4.7's names, defaults and ranges.

A subset ground stations and the GCS read (system ids, GUIDED, failsafes, fence, arming,
landing, streams), with 4.7's names (`MAV_SYSID`, `MAV_GCS_SYSID`, `MAV1_*`). ArduPilot sends
and takes every value as a float (MAVLink's C-cast encoding), so every one is of kind "f".
Which of them the mock's rules read is `gcs.sim.arducopter`.
"""

from __future__ import annotations

from gcs.autopilot import ardupilot as ap
from gcs.sim.paramdefs import ParamDef

__all__ = ["ARDUCOPTER_PARAMS"]

_BIG = 1e9

#: (name, default, min, max).
_TABLE: tuple[tuple[str, float, float, float], ...] = (
    ("ARMING_CHECK", 1, 0, _BIG),
    ("DISARM_DELAY", 10, 0, 127),
    ("FENCE_ACTION", 1, 0, 7),
    ("FENCE_ALT_MAX", 100, 10, 1000),
    ("FENCE_ENABLE", 0, 0, 1),
    ("FENCE_MARGIN", 2, 1, 10),
    ("FENCE_RADIUS", 300, 30, 10000),
    ("FENCE_TYPE", 7, 0, 15),
    ("FS_GCS_ENABLE", 0, 0, 7),
    ("FS_GCS_TIMEOUT", ap.FS_GCS_TIMEOUT_S, 2, 120),
    ("FS_OPTIONS", 0, 0, _BIG),
    ("FS_THR_ENABLE", 1, 0, 7),
    ("GUID_OPTIONS", 0, 0, _BIG),
    ("GUID_TIMEOUT", ap.GUID_TIMEOUT_S, 0.1, 5),
    ("LAND_SPEED", ap.LAND_SPEED * 100, 30, 200),
    ("MAV1_EXT_STAT", 0, 0, 50),
    ("MAV1_POSITION", 0, 0, 50),
    ("MAV_GCS_SYSID", 255, 1, 255),
    ("MAV_SYSID", 1, 1, 255),
    ("RTL_ALT", 1500, 30, 300000),
    ("WPNAV_SPEED", 1000, 10, 2000),
    ("WPNAV_SPEED_DN", 150, 10, 500),
    ("WPNAV_SPEED_UP", 250, 10, 1000),
)

ARDUCOPTER_PARAMS: dict[str, ParamDef] = {
    name: ParamDef(name, "f", float(default), float(low), float(high))
    for name, default, low, high in sorted(_TABLE)}
