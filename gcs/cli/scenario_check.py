"""The scenario a `fleetplan plan` command was given, checked as the REST API checks it: a plan
file is named as a plan with the commands that take one, and every problem of shape (type,
key, vector length) is listed at once, each naming the vehicle by id beside its index path."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gcs.errors import vehicle_at

__all__ = ["MAX_LISTED", "ScenarioProblems", "check_scenario", "is_plan", "problem_line"]

#: Problems listed before "... and N more" (a wrong file can have one per vehicle).
MAX_LISTED = 20


class ScenarioProblems(ValueError):
    """A scenario with problems: `lines` are the messages to print, one per problem."""

    def __init__(self, lines: list[str]) -> None:
        super().__init__("\n".join(lines))
        self.lines = lines


def is_plan(document: object) -> bool:
    """A plan JSON (`planner.result.Plan`: a status and trajectories) given where a scenario
    goes."""
    if not isinstance(document, dict) or "status" not in document:
        return False
    vehicles = document.get("vehicles")
    return (isinstance(vehicles, list) and bool(vehicles) and isinstance(vehicles[0], dict)
            and "position" in vehicles[0]) or "iterations" in document


def problem_line(field: str | None, reason: str, document: Any) -> str:
    """One problem as the CLI prints it: ``vehicles[1].goal (vehicle "b"): reason``."""
    vehicle = vehicle_at(field, document)
    where = field or "scenario"
    if vehicle is not None:
        where += f" (vehicle {vehicle!r})"
    return f"{where}: {reason}"


def check_scenario(document: Any, path: Path) -> None:
    """Raise `ScenarioProblems` for a plan given as a scenario, or for every problem of shape
    in `document` (at most `MAX_LISTED` lines, then how many more); None when its shape is
    right (`planner.Scenario.from_dict` then judges its meaning)."""
    if is_plan(document):
        raise ScenarioProblems([
            f"{path} is a plan, not a scenario: fly it (fleetplan fly {path} --mock, or "
            f"--fleet FLEET.json), export it (fleetplan export {path} -o SHOW.skyc), or "
            f"upload it to the page; to plan again, plan the scenario it holds (its "
            f"\"scenario\" key)"])
    from gcs.api.schemas import shape_errors

    found = shape_errors(document)
    if not found:
        return
    lines = [problem_line(item.field, item.reason, document) for item in found[:MAX_LISTED]]
    if len(found) > MAX_LISTED:
        lines.append(f"... and {len(found) - MAX_LISTED} more problems")
    raise ScenarioProblems(lines)
