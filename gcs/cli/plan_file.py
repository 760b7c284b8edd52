"""A Plan JSON file named on the command line, read for a command that uses a plan (`fly`,
`export`): one loader, so every such command words its errors the same way."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from planner.result import Plan

__all__ = ["is_scenario", "read_plan"]


def is_scenario(document: object) -> bool:
    """A scenario JSON (vehicles with start and goal, no plan status) given where a plan goes."""
    if not isinstance(document, dict) or "status" in document:
        return False
    vehicles = document.get("vehicles")
    return (isinstance(vehicles, list) and bool(vehicles) and isinstance(vehicles[0], dict)
            and "start" in vehicles[0] and "goal" in vehicles[0])


def read_plan(path: str, command: str) -> Plan:
    """The plan in `path`; ValueError with the line to print otherwise (unreadable, not
    JSON, a scenario: plan it first, then `command` the plan; a malformed plan, naming the
    field)."""
    import json
    from pathlib import Path

    from planner.errors import PlannerError
    from planner.result import Plan

    try:
        document = json.loads(Path(path).read_text())
        if is_scenario(document):
            raise ValueError(f"{path} is a scenario, not a plan: plan it first (fleetplan plan "
                             f"{path} -o PLAN.json), then {command} PLAN.json")
        return Plan.from_dict(document)
    except (OSError, json.JSONDecodeError, PlannerError) as exc:
        raise ValueError(f"cannot use plan {path}: {exc}") from None
