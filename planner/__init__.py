"""fleetplan planner: collision-free trajectories for a quadcopter fleet by sequential convex
programming (Li, Zhu & Elahi 2024, after Augugliaro, Schoellig & D'Andrea 2012).

Numerics only: no I/O, no MAVLink, no web. The public surface is re-exported here, each name
imported on first use (PEP 562), so a program that needs one module (the service's scenario
checks, `planner.errors`) does not pay for the solver stack at start.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from planner.errors import (
        FieldError,
        PlanFormatError,
        PlannerError,
        ScenarioError,
        SolverError,
    )
    from planner.model.dynamics import MotionSample, integrate, interpolate
    from planner.model.scenario import Limits, Scenario, Vehicle
    from planner.planning import plan
    from planner.result import (
        IterationProgress,
        IterationRecord,
        Plan,
        VehicleTrajectory,
        Verification,
    )

__all__ = [
    "FieldError",
    "IterationProgress",
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

#: The module each public name lives in.
_HOMES: dict[str, str] = {
    "MotionSample": "model.dynamics", "integrate": "model.dynamics",
    "interpolate": "model.dynamics",
    "FieldError": "errors", "PlanFormatError": "errors", "PlannerError": "errors",
    "ScenarioError": "errors", "SolverError": "errors",
    "plan": "planning",
    "IterationProgress": "result", "IterationRecord": "result", "Plan": "result",
    "VehicleTrajectory": "result",
    "Verification": "result",
    "Limits": "model.scenario", "Scenario": "model.scenario", "Vehicle": "model.scenario",
}


def __getattr__(name: str) -> Any:
    """Import a public name's module the first time the name is asked for."""
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'planner' has no attribute {name!r}")
    value = getattr(import_module(f"planner.{home}"), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
