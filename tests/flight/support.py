"""Test helpers: free UDP port blocks and smooth plans built without the SCP planner."""

from __future__ import annotations

from typing import Any

import numpy as np

from gcs.fleet.fleetfile import FlightOptions
from gcs.sim.ports import free_mock_fleet_ports, free_udp_base
from planner.model.flatness import body_rates, jerk_from_accelerations, thrust
from planner.model.scenario import Scenario
from planner.result import Plan, VehicleTrajectory
from planner.scp.first_qp import unit_profile
from planner.verification.verify import verify

__all__ = [
    "FAST_MOCK",
    "QUICK",
    "QUICK_MOCK",
    "QUICK_MOCK_ENV",
    "QUICK_MOCK_SETTINGS",
    "STACKED",
    "STACKED_HOMES",
    "free_port_block",
    "line_scenario",
    "mock_ports",
    "short_line",
    "smooth_plan",
]

#: Mock settings that shorten a flight's landing, not what it checks: PX4's MPC_LAND_SPEED
#: and COM_DISARM_LAND set to other legal values (land at 1 m/s, disarm 0.5 s after).
QUICK_MOCK: dict[str, Any] = {"land_speed": 1.0, "disarm_after_land": 0.5}

#: `QUICK_MOCK` with HEARTBEAT, SYS_STATUS and EXTENDED_SYS_STATE at 5 Hz (PX4: 1 Hz by
#: default, a `mavlink stream -r` setting): each mode, arming and disarming change shows in
#: HEARTBEAT within 0.2 s instead of 1 s, which saves the GCS about 1 s per confirmation.
FAST_MOCK: dict[str, Any] = {**QUICK_MOCK, "status_rate": 5.0}

#: The service settings that give an in-process service's mock vehicles `FAST_MOCK`.
QUICK_MOCK_SETTINGS: dict[str, float] = {
    "mock_land_speed": FAST_MOCK["land_speed"],
    "mock_disarm_after_land_s": FAST_MOCK["disarm_after_land"],
    "mock_status_rate_hz": FAST_MOCK["status_rate"],
}

#: `QUICK_MOCK_SETTINGS` as the environment of a `fleetplan serve` child.
QUICK_MOCK_ENV: dict[str, str] = {
    f"FLEETPLAN_{name.upper()}": str(value) for name, value in QUICK_MOCK_SETTINGS.items()
}

#: Flight options for tests: a short hold at the goals and prestream, a 2 m/s climb.
QUICK = FlightOptions(hold_at_goal=0.5, prestream=0.3, climb_speed=2.0)


def free_port_block(count: int) -> int:
    """A base port such that UDP ports base..base+count-1 are free on 127.0.0.1 right now."""
    return free_udp_base(range(count))


def mock_ports(count: int) -> dict[str, int]:
    """gcs_base_port / listen_base_port keyword arguments for a MockFleet of `count`, free now."""
    return free_mock_fleet_ports(count)


def smooth_plan(scenario_dict: dict[str, Any]) -> Plan:
    """A plan whose vehicles fly rest-to-rest along straight lines (no SCP), verified.

    Each vehicle follows the planner's own minimum-thrust unit profile scaled by its move,
    which meets every boundary condition; the verification is computed for real. Tests use
    scenarios whose straight lines are far apart (the real planner is used where that
    matters), so these plans are separated.
    """
    scenario = Scenario.from_dict(scenario_dict)
    k, dt = scenario.steps, scenario.dt
    phi_p, phi_v, phi_a = unit_profile(k, dt)
    vehicles = []
    for v in scenario.vehicles:
        move = v.goal - v.start
        acc = np.outer(phi_a, move)
        jerk = jerk_from_accelerations(acc, dt)
        vehicles.append(VehicleTrajectory(
            id=v.id, t=np.arange(k + 1) * dt, position=v.start + np.outer(phi_p, move),
            velocity=np.outer(phi_v, move), acceleration=acc, jerk=jerk, thrust=thrust(acc),
            body_rates=body_rates(acc, jerk)))
    positions = np.stack([v.position for v in vehicles])
    velocities = np.stack([v.velocity for v in vehicles])
    accelerations = np.stack([v.acceleration for v in vehicles])
    verification = verify(scenario, positions, velocities, accelerations)
    assert verification.verified, verification.failures()
    return Plan(status="converged", message="test plan", scenario=scenario,
                vehicles=tuple(vehicles), iterations=(), timing={},
                verification=verification, solver="test")


def line_scenario(count: int, *, dt: float = 0.2, steps: int = 30, spacing: float = 3.0,
                  travel: float = 2.0, altitude: float = 1.5) -> dict[str, Any]:
    """`count` vehicles side by side, each flying `travel` m along y at `altitude`."""
    vehicles = [{"id": f"uav{i + 1}", "start": [spacing * i + 1.0, 1.0, altitude],
                 "goal": [spacing * i + 1.0, 1.0 + travel, altitude]} for i in range(count)]
    return {
        "name": f"line{count}", "dt": dt, "steps": steps, "min_separation": 1.0,
        "limits": {"position_min": [0.0, 0.0, 0.0],
                   "position_max": [spacing * count + 2.0, travel + 2.0, 5.0],
                   "velocity_max": [3.0, 3.0, 3.0], "acceleration_max": [5.0, 5.0, 5.0]},
        "vehicles": vehicles,
    }


def short_line(count: int, *, steps: int = 15, altitude: float = 1.0,
               **kw: Any) -> dict[str, Any]:
    """`line_scenario` flown in 3 s at 1 m: a whole flight in a few seconds of real time."""
    return line_scenario(count, steps=steps, altitude=altitude, **kw)


#: Two vehicles stacked 0.84 m apart vertically and 0.55 m horizontally (1.004 m apart),
#: flying side by side along y: landing each straight down brings them 0.55 m apart.
STACKED = {
    "name": "stacked", "dt": 0.2, "steps": 20, "min_separation": 1.0,
    "limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [5.0, 5.0, 3.0],
               "velocity_max": [2.0, 2.0, 2.0], "acceleration_max": [3.0, 3.0, 3.0]},
    "vehicles": [{"id": "low", "start": [2.0, 1.0, 1.08], "goal": [2.0, 3.0, 1.08]},
                 {"id": "high", "start": [2.55, 1.0, 1.92], "goal": [2.55, 3.0, 1.92]}],
}
#: Where the STACKED pair stands on the ground (world frame).
STACKED_HOMES = [[0.8, 1.0, 0.0], [3.75, 1.0, 0.0]]
