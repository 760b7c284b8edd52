"""Show designs the show, export and API tests share: a 9-drone sequence taking off from a
ground grid, the same with lights, a fleet file standing on homes, and a plan written as
Skybrush CSV."""

from __future__ import annotations

import copy
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from fastapi.testclient import TestClient

from gcs.export.lightcode import colors_at
from gcs.export.lights import light_changes
from gcs.export.skyc import write_skyc
from gcs.show.design import read_design
from gcs.show.to_sequence import to_sequence
from planner import Plan
from planner.families.generators import show_sequence

__all__ = ["BLUE", "FLEET_HOMES", "GRID", "csv_zip", "fleet_dict", "ground_show", "light_design",
           "post_sequence", "skyc_import", "slot_colors", "small_ground_show"]

#: A 3 x 3 ground grid 2 m apart in x and 0.8 m in y (tighter than R = 1 m in y).
GRID = {"origin": [-2.0, -2.0], "columns": 3, "rows": 3, "spacing": [2.0, 0.8]}
#: The same grid's cells as homes (world frame, on the ground).
FLEET_HOMES = [[-2.0 + 2.0 * c, -2.0 + 0.8 * r, 0.0] for r in range(3) for c in range(3)]
BLUE = (0, 0, 255)


def ground_show(**ground: Any) -> dict[str, Any]:
    """A 9-drone sequence taking off from `GRID`; `ground` adds or replaces top-level keys
    (``landing``, ``takeoff``)."""
    data = show_sequence(9, seed=2, hold=1.0)
    data["limits"]["position_min"][2] = 0.0
    data["takeoff"] = {"grid": GRID}
    data.update(ground)
    return data


def small_ground_show() -> dict[str, Any]:
    """A 4-drone show of about 20 s, quick to fly: it takes off from a 2 x 2 ground grid 2 m
    apart (one wave: R = 1 m), flies a square and a diamond, and lands on the grid."""
    return {"name": "ground4", "dt": 0.2, "min_separation": 1.0, "assignment": "free",
            "limits": {"position_min": [-4.0, -4.0, 0.0], "position_max": [4.0, 4.0, 5.0],
                       "acceleration_max": [3.0, 3.0, 3.0], "velocity_max": [3.0, 3.0, 3.0],
                       "jerk_max": [5.0, 5.0, 5.0]},
            "vehicles": ["uav1", "uav2", "uav3", "uav4"],
            "takeoff": {"grid": {"origin": [-1.0, -1.0], "columns": 2, "rows": 2,
                                 "spacing": [2.0, 2.0]}, "duration": 4.0},
            "landing": {"duration": 4.0},
            "formations": [
                {"name": "square", "hold": 1.0, "positions": [
                    [-1.5, -1.5, 3.0], [1.5, -1.5, 3.0], [-1.5, 1.5, 3.0], [1.5, 1.5, 3.0]]},
                {"name": "diamond", "duration": 4.0, "hold": 1.0, "positions": [
                    [0.0, -2.0, 3.5], [2.0, 0.0, 3.0], [-2.0, 0.0, 3.0], [0.0, 2.0, 3.5]]}]}


def slot_colors(count: int) -> list[list[int]]:
    """A distinct colour per slot."""
    return [[20 * i, 255 - 20 * i, 7 * i] for i in range(count)]


def light_design() -> dict[str, Any]:
    """grid (red) -> sphere (a colour per slot, fade) -> grid (blue, hold) -> sphere (no
    colour: keeps blue, through black)."""
    data = show_sequence(9, seed=2, hold=1.0)
    grid, sphere, _ = data["formations"]
    data["formations"] = [
        {**grid, "color": "#ff0000"},
        {**sphere, "color": slot_colors(9), "lights": "fade"},
        {**data["formations"][2], "color": list(BLUE), "lights": "hold"},
        {**copy.deepcopy(sphere), "lights": "black"},
    ]
    return data


def csv_zip(plan: Plan, path: Path, rate: float = 25.0) -> Path:
    """The plan as Skybrush CSV (7 columns, a file per drone), zipped."""
    times = np.arange(0.0, plan.scenario.horizon + 1e-9, 1.0 / rate)
    sampled = plan.sample(times).position
    with zipfile.ZipFile(path, "w") as archive:
        for n, track in enumerate(plan.vehicles):
            changes = light_changes(plan, track.id)
            assert changes is not None
            rgb = np.rint(colors_at(changes, times)).astype(int)
            rows = ["Time [msec],x [m],y [m],z [m],Red,Green,Blue"] + [
                f"{round(t * 1000)},{x:.4f},{y:.4f},{z:.4f},{r},{g},{b}"
                for t, (x, y, z), (r, g, b) in zip(times, sampled[n], rgb, strict=True)]
            archive.writestr(f"{track.id}.csv", "\n".join(rows) + "\n")
    return path


def skyc_import(plan: Plan, path: Path) -> dict[str, Any]:
    """The plan written as a `.skyc` at `path`, and the sequence `fleetplan import` (and
    POST /api/imports, with the default options) reads from it."""
    write_skyc(plan, path)
    design = read_design(path)
    return to_sequence(design.tracks, name=design.title, file=path.name,
                       validation=design.validation)


def fleet_dict(ids: list[str], homes: list[list[float]]) -> dict[str, Any]:
    """A fleet file of `ids` standing at `homes` (listed in reverse, not the show's order)."""
    vehicles = [{"id": vid, "connection": f"udpin:127.0.0.1:{14540 + n}", "system_id": n + 1,
                 "home": home} for n, (vid, home) in enumerate(zip(ids, homes, strict=True))]
    return {"vehicles": vehicles[::-1]}


def post_sequence(client: TestClient, body: dict[str, Any]) -> dict[str, Any]:
    """POST a sequence (or scenario) and wait for its plan; the mission document (201)."""
    response = client.post("/api/missions?wait=60", json=body)
    assert response.status_code == 201, response.text
    return response.json()
