"""gcs.frames: ENU world <-> each vehicle's LOCAL_NED, headings, geodetic homes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs import frames


def test_world_to_ned_by_hand() -> None:
    home = np.array([10.0, 20.0, 1.0])
    # 3 m east, 4 m north, 2 m up of the home: NED x = north, y = east, z = down
    p = frames.world_to_ned(home + np.array([3.0, 4.0, 2.0]), home)
    np.testing.assert_allclose(p, [4.0, 3.0, -2.0])
    np.testing.assert_allclose(frames.ned_to_world(p, home), home + np.array([3.0, 4.0, 2.0]))


def test_vectors_rotate_without_the_home() -> None:
    np.testing.assert_allclose(frames.world_vector_to_ned([1.0, 2.0, 3.0]), [2.0, 1.0, -3.0])
    np.testing.assert_allclose(frames.ned_vector_to_world([2.0, 1.0, -3.0]), [1.0, 2.0, 3.0])


def test_round_trip_many_points_and_homes() -> None:
    rng = np.random.default_rng(1)
    points = rng.uniform(-100, 100, size=(50, 3))
    homes = rng.uniform(-100, 100, size=(50, 3))
    ned = frames.world_to_ned(points, homes)
    np.testing.assert_allclose(frames.ned_to_world(ned, homes), points, atol=1e-12)
    # the distance to the vehicle's own home is preserved, the z axis flips
    np.testing.assert_allclose(np.linalg.norm(ned, axis=1),
                               np.linalg.norm(points - homes, axis=1))
    np.testing.assert_allclose(ned[:, 2], -(points - homes)[:, 2])


def test_two_vehicles_same_world_point_different_local() -> None:
    point = np.array([5.0, 5.0, 2.0])
    a = frames.world_to_ned(point, [0.0, 0.0, 0.0])
    b = frames.world_to_ned(point, [5.0, 0.0, 0.0])
    np.testing.assert_allclose(a, [5.0, 5.0, -2.0])
    np.testing.assert_allclose(b, [5.0, 0.0, -2.0])


@pytest.mark.parametrize(("enu", "ned"), [(0.0, math.pi / 2), (math.pi / 2, 0.0),
                                           (math.pi, -math.pi / 2), (-math.pi / 2, math.pi)])
def test_yaw(enu: float, ned: float) -> None:
    assert frames.world_yaw_to_ned(enu) == pytest.approx(ned)
    assert frames.ned_yaw_to_world(ned) == pytest.approx(frames.wrap_angle(enu))


def test_geodetic_round_trip_and_scale() -> None:
    origin = frames.Geodetic(47.397742, 8.545594, 488.0)
    for enu in ([0.0, 0.0, 0.0], [100.0, -50.0, 3.0], [-1234.5, 2000.0, -20.0]):
        g = frames.enu_to_geodetic(enu, origin)
        np.testing.assert_allclose(frames.geodetic_to_enu(g, origin), enu, atol=1e-6)
    # one arc-second of latitude is about 30.9 m at this latitude; 1e-3 deg of longitude
    # is 111.3 km * cos(lat) / 1000
    north = frames.geodetic_to_enu(frames.Geodetic(47.397742 + 1 / 3600, 8.545594, 488.0),
                                   origin)
    assert north[1] == pytest.approx(30.87, abs=0.05)
    east = frames.geodetic_to_enu(frames.Geodetic(47.397742, 8.545594 + 1e-3, 488.0), origin)
    assert east[0] == pytest.approx(111.32 * math.cos(math.radians(47.397742)), rel=2e-3)
