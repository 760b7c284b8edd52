"""Frame conversions: the planner's world frame and each vehicle's MAVLink LOCAL_NED frame.

The planner's world frame is ENU (x east, y north, z up), one origin for the whole fleet. A PX4
vehicle's LOCAL_NED frame (x north, y east, z down) has its origin at that vehicle's own EKF
origin, which is where it started (its home), so it differs from vehicle to vehicle:

    p_ned = R_ENU_TO_NED @ (p_world - home_world)        (positions)
    v_ned = R_ENU_TO_NED @ v_world                       (velocities, accelerations)

R_ENU_TO_NED swaps x and y and negates z; it is symmetric and its own inverse. This module is
the only place in `gcs` where frames are converted, including headings (ENU yaw is measured
from +x east counter-clockwise, NED yaw from north clockwise) and geodetic coordinates (WGS84,
by pymap3d), which place a vehicle's home in the world frame from the origin it reports and
the geofence on the Earth (`world_to_geodetic`), and the show frame that a Skybrush show
file (`gcs.export.skyc`) is written in.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
from numpy.typing import ArrayLike

from planner.types import FloatArray

__all__ = [
    "R_ENU_TO_NED",
    "SHOW_AXES",
    "SHOW_ORIENTATION_DEG",
    "Geodetic",
    "enu_to_geodetic",
    "geodetic_to_enu",
    "ned_to_world",
    "ned_vector_to_world",
    "ned_yaw_to_world",
    "world_to_geodetic",
    "world_to_ned",
    "world_to_show",
    "world_vector_to_ned",
    "world_yaw_to_ned",
]


#: ENU -> NED rotation (also NED -> ENU: the matrix is symmetric and orthogonal).
R_ENU_TO_NED: FloatArray = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
R_ENU_TO_NED.setflags(write=False)


def world_vector_to_ned(v_world: ArrayLike) -> FloatArray:
    """A free vector (velocity, acceleration) from ENU to NED; shape (..., 3)."""
    return np.asarray(v_world, dtype=float) @ R_ENU_TO_NED.T


def ned_vector_to_world(v_ned: ArrayLike) -> FloatArray:
    """A free vector from NED to ENU; shape (..., 3)."""
    return np.asarray(v_ned, dtype=float) @ R_ENU_TO_NED.T


def world_to_ned(p_world: ArrayLike, home_world: ArrayLike) -> FloatArray:
    """World (ENU) positions to a vehicle's LOCAL_NED, whose origin is `home_world`."""
    return world_vector_to_ned(np.asarray(p_world, dtype=float) - np.asarray(home_world, float))


def ned_to_world(p_ned: ArrayLike, home_world: ArrayLike) -> FloatArray:
    """A vehicle's LOCAL_NED positions back to the world frame (ENU)."""
    world: FloatArray = ned_vector_to_world(p_ned) + np.asarray(home_world, dtype=float)
    return world


def world_yaw_to_ned(yaw_world: float) -> float:
    """Heading from ENU (from +x east, counter-clockwise) to NED (from north, clockwise), in
    (-pi, pi]."""
    return wrap_angle(math.pi / 2.0 - yaw_world)


def ned_yaw_to_world(yaw_ned: float) -> float:
    """Heading from NED to ENU, in (-pi, pi]."""
    return wrap_angle(math.pi / 2.0 - yaw_ned)


def wrap_angle(angle: float) -> float:
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


# ------------------------------------------------------------------------------ geodetic

class Geodetic(tuple[float, float, float]):
    """(lat, lon, alt): WGS84 latitude and longitude in degrees, altitude in metres (AMSL as
    PX4 reports it; only differences of altitude matter here)."""

    __slots__ = ()

    def __new__(cls, lat: float, lon: float, alt: float) -> Geodetic:
        return super().__new__(cls, (float(lat), float(lon), float(alt)))

    @property
    def lat(self) -> float:
        return self[0]

    @property
    def lon(self) -> float:
        return self[1]

    @property
    def alt(self) -> float:
        return self[2]


def geodetic_to_enu(point: Geodetic, origin: Geodetic) -> FloatArray:
    """`point` in the local ENU tangent frame at `origin` (exact WGS84, metres; pymap3d)."""
    return np.array(pymap3d.geodetic2enu(point.lat, point.lon, point.alt,
                                         origin.lat, origin.lon, origin.alt), dtype=float)


def enu_to_geodetic(p_enu: ArrayLike, origin: Geodetic) -> Geodetic:
    """Inverse of `geodetic_to_enu`."""
    e, n, u = (float(c) for c in np.asarray(p_enu, dtype=float))
    lat, lon, alt = pymap3d.enu2geodetic(e, n, u, origin.lat, origin.lon, origin.alt)
    return Geodetic(float(lat), float(lon), float(alt))


def world_to_geodetic(p_world: ArrayLike, home_world: ArrayLike,
                      origin: Geodetic) -> FloatArray:
    """World (ENU) points placed on the Earth by a vehicle whose LOCAL_NED origin (home, in
    the world frame) is at `origin`: (..., 3) -> (..., 3) latitude, longitude (degrees) and
    altitude (m). With `home_world` 0 and `origin` the fleet's world_origin it places world
    points directly."""
    rel = np.asarray(p_world, dtype=float) - np.asarray(home_world, dtype=float)
    lat, lon, alt = pymap3d.enu2geodetic(rel[..., 0], rel[..., 1], rel[..., 2],
                                         origin.lat, origin.lon, origin.alt)
    return np.stack([np.asarray(lat, float), np.asarray(lon, float), np.asarray(alt, float)],
                    axis=-1)


# ------------------------------------------------------------------------ show frame

#: Skybrush's show coordinate system: a flat-Earth frame, right-handed and z up ("nwu": x
#: along the show's heading, y 90 degrees to its left, z up), placed on the Earth by an origin
#: and the heading of its x axis from north towards east (degrees). Its z is the height above
#: the origin, as the world frame's z.
SHOW_AXES = "nwu"
#: The heading of the show frame's x axis, degrees from north towards east: with x pointing
#: east, y points north, so the show frame is the world frame (ENU) itself.
SHOW_ORIENTATION_DEG = 90.0


def world_to_show(p_world: ArrayLike) -> FloatArray:
    """World (ENU) positions in the show frame of `SHOW_AXES` at `SHOW_ORIENTATION_DEG`: the
    same numbers (x east, y north, z up), so a show file needs no rotation; (..., 3)."""
    return np.array(p_world, dtype=float)
