"""Test helpers: free UDP port blocks and smooth plans built without the SCP planner."""

from __future__ import annotations

import random
import socket
from typing import Any

import numpy as np

from planner.dynamics import integrate
from planner.flatness import body_rates, jerk_from_accelerations, thrust
from planner.result import Plan, VehicleTrajectory, Verification
from planner.scenario import Scenario


def free_port_block(count: int, attempts: int = 200) -> int:
    """A base port such that UDP ports base..base+count-1 are free on 127.0.0.1 right now.

    Random bases in a range far from PX4's 14540/14550/14580 so that concurrent test suites
    on this machine do not collide.
    """
    rng = random.Random()
    for _ in range(attempts):
        base = rng.randrange(20000, 60000 - count)
        sockets = []
        try:
            for port in range(base, base + count):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                sockets.append(s)
                s.bind(("127.0.0.1", port))
        except OSError:
            continue
        finally:
            for s in sockets:
                s.close()
        return base
    raise RuntimeError("no free UDP port block found")


def mock_ports(count: int) -> dict[str, int]:
    """gcs_base_port / listen_base_port keyword arguments for a MockFleet of `count`."""
    base = free_port_block(2 * count)
    return {"gcs_base_port": base, "listen_base_port": base + count}


def smooth_plan(scenario_dict: dict[str, Any]) -> Plan:
    """A verified-looking Plan whose vehicles fly rest-to-rest along straight lines.

    Accelerations a_k = c * sin(2 pi (k + 1/2) / K) (k = 0..K-1) sum to zero, so every vehicle
    ends at rest; c is chosen so it ends exactly at its goal. Not collision-checked: tests use
    scenarios whose straight lines are far apart (the real planner is used where that matters).
    """
    scenario = Scenario.from_dict(scenario_dict)
    k, dt = scenario.steps, scenario.dt
    shape = np.sin(2 * np.pi * (np.arange(k) + 0.5) / k)
    p_unit, _ = integrate(np.zeros(3), np.zeros(3), np.outer(shape, np.ones(3)), dt)
    per_unit = p_unit[-1, 0]
    vehicles = []
    for v in scenario.vehicles:
        c = (v.goal - v.start) / per_unit
        acc = np.outer(shape, c)
        pos, vel = integrate(v.start, np.zeros(3), acc, dt)
        jerk = jerk_from_accelerations(acc, dt)
        vehicles.append(VehicleTrajectory(
            id=v.id, t=np.arange(k + 1) * dt, position=pos, velocity=vel, acceleration=acc,
            jerk=jerk, thrust=thrust(acc), body_rates=body_rates(acc, jerk)))
    plan = Plan(status="converged", message="test plan", scenario=scenario,
                vehicles=tuple(vehicles), iterations=(), timing={}, verification=None,
                solver="test")
    positions = plan.sample(np.linspace(0, scenario.horizon, 2001)).position
    n = len(vehicles)
    sep = np.inf
    for i in range(n):
        for j in range(i + 1, n):
            d = np.linalg.norm((positions[i] - positions[j]) / scenario.separation_scale, axis=1)
            sep = min(sep, float(d.min()))
    verification = Verification(
        min_separation=sep, min_separation_continuous=sep, closest_pair=[],
        closest_time=0.0, max_violation={}, boundary_error={}, thrust_range=[0.0, 0.0],
        body_rate_peak=0.0, flyable=True, separated=sep >= scenario.min_separation,
        within_bounds=True, separation_tolerance=1e-3, bound_tolerance=1e-3)
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
