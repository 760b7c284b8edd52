"""fleetplan planner: collision-free trajectories for a quadcopter fleet by sequential convex
programming (Li, Zhu & Elahi 2024, after Augugliaro, Schoellig & D'Andrea 2012).

Numerics only: no I/O, no MAVLink, no web. The public surface is re-exported here.
"""

from planner.dynamics import MotionSample, integrate, interpolate
from planner.errors import FieldError, PlanFormatError, PlannerError, ScenarioError, SolverError
from planner.planning import plan
from planner.result import IterationRecord, Plan, VehicleTrajectory, Verification
from planner.scenario import Limits, Scenario, Vehicle

__all__ = [
    "FieldError",
    "IterationRecord",
    "Limits",
    "MotionSample",
    "Plan",
    "PlanFormatError",
    "PlannerError",
    "Scenario",
    "ScenarioError",
    "SolverError",
    "Vehicle",
    "VehicleTrajectory",
    "Verification",
    "integrate",
    "interpolate",
    "plan",
]
