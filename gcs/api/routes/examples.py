"""/api/examples: the scenarios bundled with the planner (the paper's cases and larger ones),
which the browser page offers as presets."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Annotated, Any

from fastapi import APIRouter, Path
from pydantic import BaseModel

from gcs.api.errors import error_responses
from gcs.errors import NotFound

__all__ = ["router"]

router = APIRouter(prefix="/examples", tags=["examples"])


class ExampleOut(BaseModel):
    """A bundled scenario: its name, size and where to get it."""

    model_config = {"json_schema_extra": {"examples": [
        {"name": "paper-circle4", "vehicles": 4, "url": "/api/examples/paper-circle4"}]}}

    name: str
    vehicles: int
    url: str


@cache
def _examples() -> dict[str, dict[str, Any]]:
    folder = resources.files("planner").joinpath("examples")
    found = {}
    for entry in folder.iterdir():
        if entry.name.endswith(".json"):
            found[entry.name.removesuffix(".json")] = json.loads(entry.read_text())
    return dict(sorted(found.items(), key=lambda kv: (len(kv[1]["vehicles"]), kv[0])))


@router.get("", response_model=list[ExampleOut], summary="List bundled example scenarios")
def list_examples() -> list[dict[str, Any]]:
    """Names and sizes, smallest first."""
    return [
        {"name": name, "vehicles": len(s["vehicles"]), "url": f"/api/examples/{name}"}
        for name, s in _examples().items()
    ]


@router.get("/{name}", summary="One example scenario", responses=error_responses(404))
def get_example(
    name: Annotated[str, Path(max_length=100, examples=["paper-circle4"])],
) -> dict[str, Any]:
    """The scenario JSON, ready to POST to /api/missions."""
    scenario = _examples().get(name)
    if scenario is None:
        raise NotFound("name", f"no example named {name!r}; see GET /api/examples")
    return scenario
