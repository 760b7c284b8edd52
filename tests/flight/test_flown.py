"""gcs.flight.timeline.flown: the flight's plans in flight time and the motions off them."""

from __future__ import annotations

import numpy as np
import pytest

from gcs.flight.timeline.flown import FlownPlans, Motion, shifted
from planner.model.fixed import braking_motion, landing_motion
from tests.flight.support import short_line, smooth_plan


def test_a_switched_plan_takes_over_at_its_start_and_a_dropped_vehicle_follows_its_motion(
) -> None:
    first = smooth_plan(short_line(2, steps=15))
    second = smooth_plan(short_line(1, steps=10) | {"vehicles": [
        {"id": "uav1", "start": [1.0, 2.0, 1.0], "goal": [1.0, 3.0, 1.0]}]})
    flown = FlownPlans.of(first)
    assert flown.horizon == pytest.approx(3.0)
    drop = landing_motion("uav2", [4.0, 2.0, 1.0], [0.0, 0.5, 0.0], 0.2, 2.0, 1.0, 0.3)
    flown.switch(1.5, second)
    flown.motions["uav2"] = Motion(1.5, drop, 0.2, True)
    assert flown.horizon == pytest.approx(1.5 + 2.0)
    times = np.array([1.0, 1.5, 2.5])
    uav1 = flown.position("uav1", times)
    np.testing.assert_allclose(uav1[0], first.sample([1.0]).position[0, 0])
    np.testing.assert_allclose(uav1[1], [1.0, 2.0, 1.0])  # the new plan's start
    np.testing.assert_allclose(uav1[2], second.sample([1.0]).position[0, 0])
    uav2 = flown.position("uav2", times)
    np.testing.assert_allclose(uav2[0], first.sample([1.0]).position[1, 0])
    np.testing.assert_allclose(uav2[1:], drop.state([0.0, 1.0], 0.2)[0])
    assert flown.planned("uav1", 2.0) and not flown.planned("uav2", 2.0)
    assert flown.predicted("uav2", 1.0) is None
    np.testing.assert_allclose(flown.predicted("uav2", 10.0), drop.positions[-1])


def test_a_motion_shifted_to_a_later_switch_is_the_same_motion_from_there() -> None:
    stop = braking_motion("uav3", [0.0, 0.0, 1.0], [2.0, 0.0, 0.0], 0.2, 1.0, margin=0.5)
    motion = Motion(3.0, stop, 0.2, False)
    later = shifted(motion, 3.3)
    assert later.margin == 0.5 and later.id == "uav3"
    t = np.arange(len(later)) * 0.2
    np.testing.assert_allclose(later.positions, stop.state(t + 0.3, 0.2)[0], atol=1e-12)
    np.testing.assert_allclose(later.positions[-1], stop.positions[-1], atol=1e-9)
    np.testing.assert_allclose(later.velocities[-1], 0.0)
    rested = shifted(motion, 100.0)  # long after it ended: at rest where it stopped
    assert len(rested) == 1
    np.testing.assert_allclose(rested.positions[0], stop.positions[-1])
