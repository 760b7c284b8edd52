"""A plan's geofence as a QGroundControl ``.plan`` file (its ``geoFence`` section), for
operators who also watch the flight in QGC.

The format (QGC's `PlanMasterController`, `GeoFenceController` file version 2)::

    {"fileType": "Plan", "version": 1, "groundStation": "fleetplan",
     "mission": {"version": 2, "firmwareType": 12, "vehicleType": 2, "cruiseSpeed": ...,
                 "hoverSpeed": ..., "items": [], "plannedHomePosition": [lat, lon, alt]},
     "geoFence": {"version": 2,
                  "polygons": [{"polygon": [[lat, lon], ...], "inclusion": true, "version": 1}],
                  "circles": [{"circle": {"center": [lat, lon], "radius": r},
                               "inclusion": false, "version": 1}]},
     "rallyPoints": {"version": 2, "points": []}}

The shapes are the ones each vehicle is given (`gcs.geofence`), placed from the world origin
(the world frame's (0, 0, 0) on the Earth): one file for the whole fleet. The mission is
empty: the vehicles fly offboard setpoints, not a QGC mission.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gcs.frames import Geodetic
from gcs.geofence import WorldFence, place_shapes

__all__ = ["QGC_PLAN_MEDIA_TYPE", "qgc_plan"]

QGC_PLAN_MEDIA_TYPE = "application/json"
_PX4 = 12  # MAV_AUTOPILOT_PX4
_QUADROTOR = 2  # MAV_TYPE_QUADROTOR
_DECIMALS = 9  # degrees: 0.1 mm, beyond QGC's and PX4's own 1e-7


def qgc_plan(fence: WorldFence, origin: Geodetic, *, cruise_speed: float = 5.0,
             hover_speed: float = 5.0) -> dict[str, Any]:
    """The `.plan` document of `fence` placed from `origin` (an altitude that is not a number,
    an origin given without one, is written as 0)."""
    alt = origin.alt if math.isfinite(origin.alt) else 0.0
    origin = Geodetic(origin.lat, origin.lon, alt)  # the shapes lie on the ground either way
    polygons: list[dict[str, Any]] = []
    circles: list[dict[str, Any]] = []
    for shape, lat_lon in place_shapes(fence, np.zeros(3), origin):
        points = np.round(lat_lon, _DECIMALS).tolist()
        if shape.radius is not None:
            circles.append({"circle": {"center": points[0], "radius": shape.radius},
                            "inclusion": shape.inclusion, "version": 1})
        else:
            polygons.append({"polygon": points, "inclusion": shape.inclusion, "version": 1})
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "fleetplan",
        "mission": {"version": 2, "firmwareType": _PX4, "vehicleType": _QUADROTOR,
                    "cruiseSpeed": cruise_speed, "hoverSpeed": hover_speed, "items": [],
                    "plannedHomePosition": [origin.lat, origin.lon, alt]},
        "geoFence": {"version": 2, "polygons": polygons, "circles": circles},
        "rallyPoints": {"version": 2, "points": []},
    }
