"""The .skyc export read back by an independent reader (`tests.export.reader`): the file
reproduces the plan's motion (`Plan.sample`) within 1 cm at every time and exactly at the
keyframes, and carries the fields Skybrush reads, with the scenario's limits."""

from __future__ import annotations

import base64
import dataclasses
import io
import json
import math
import zipfile
from typing import Any

import numpy as np
import pytest

from gcs.errors import ExportError
from gcs.export.skyc import (
    SKYC_MEDIA_TYPE,
    check_exportable,
    keyframe_count,
    parse_origin,
    skyc_chunks,
)
from gcs.frames import SHOW_AXES, SHOW_ORIENTATION_DEG, world_to_show
from planner import Plan, Scenario
from planner import plan as make_plan
from planner.families.generators import show_sequence
from planner.methods.sequence import plan_sequence
from tests.export.reader import evaluate, read_show, velocity
from tests.paths import EXAMPLES

#: What the export promises: the file's motion within this of the plan's, at every time (m).
PROMISE_M = 0.01


@pytest.fixture(scope="module")
def circle() -> Plan:
    scenario = Scenario.from_dict(json.loads((EXAMPLES / "paper-circle4.json").read_text()))
    plan = make_plan(scenario)
    assert plan.ok, plan.problems()
    return plan


@pytest.fixture(scope="module")
def sequence() -> Plan:
    """grid -> sphere -> grid with 1 s holds: legs, holds at rest, formation names."""
    plan = plan_sequence(show_sequence(9, seed=2, hold=1.0)).to_plan()
    assert plan.ok, plan.problems()
    return plan


def _export(plan: Plan, **options: Any) -> bytes:
    return b"".join(skyc_chunks(plan, **options))


def _drones(show: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {d["settings"]["name"]: d["settings"] for d in show["swarm"]["drones"]}


def _times(plan: Plan) -> np.ndarray:
    """Every step, four points inside each step, and 500 random times (seeded)."""
    horizon = plan.scenario.horizon
    grid = np.linspace(0.0, horizon, 4 * plan.scenario.steps + 1)
    rng = np.random.default_rng(7)
    return np.sort(np.concatenate([grid, rng.uniform(0.0, horizon, 500)]))


@pytest.mark.parametrize("name", ["circle", "sequence"])
def test_the_file_reproduces_the_plan_within_a_centimetre(name: str, request) -> None:
    plan: Plan = request.getfixturevalue(name)
    drones = _drones(read_show(_export(plan)))
    times = _times(plan)
    expected = plan.sample(times)
    worst = 0.0
    for n, track in enumerate(plan.vehicles):
        trajectory = drones[track.id]["trajectory"]
        got = evaluate(trajectory, times)
        want = world_to_show(expected.position[n])
        error = float(np.max(np.linalg.norm(got - want, axis=1)))
        worst = max(worst, error)
        # Exact at the keyframes (to the micrometre the file is rounded to) ...
        keytimes = np.array([k[0] for k in trajectory["points"]])
        at_keys = world_to_show(plan.sample(keytimes).position[n])
        np.testing.assert_allclose([k[1] for k in trajectory["points"]], at_keys, atol=1e-6)
        # ... and the speed a player derives from the curves is the plan's.
        inside = times[(times > 0.0) & (times < plan.scenario.horizon)]
        np.testing.assert_allclose(velocity(trajectory, inside),
                                   world_to_show(plan.sample(inside).velocity[n]), atol=1e-4)
    assert worst <= PROMISE_M
    # A cubic per step carries the quadratic exactly: nothing is left but the rounding.
    assert worst < 1e-5


def test_one_cubic_per_moving_step_and_one_segment_per_rest(circle: Plan,
                                                            sequence: Plan) -> None:
    for plan in (circle, sequence):
        for settings in _drones(read_show(_export(plan))).values():
            points = settings["trajectory"]["points"]
            assert points[0][2] == []  # the first keyframe has no controls
            assert {len(k[2]) for k in points[1:]} <= {0, 2}
            steps_ms = np.diff([round(k[0] * 1000) for k in points])
            dt_ms = round(plan.scenario.dt * 1000)
            assert np.all(steps_ms > 0) and np.all(steps_ms % dt_ms == 0)
            # A segment longer than one step is a rest: no controls, start = end.
            for before, after, span in zip(points, points[1:], steps_ms, strict=False):
                if span > dt_ms:
                    assert after[2] == [] and after[1] == before[1]
    # The sequence holds at rest (1 s holds, the legs' ends): far fewer keyframes than steps.
    counts = [len(s["trajectory"]["points"]) for s in _drones(read_show(_export(sequence)))
              .values()]
    assert max(counts) < sequence.scenario.steps + 1
    assert keyframe_count(sequence) == len(sequence.vehicles) * (sequence.scenario.steps + 1)


def test_fields_are_those_skybrush_reads_with_the_scenario_limits(circle: Plan) -> None:
    data = _export(circle, show_id="m1")
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        assert archive.namelist() == ["show.json"]
        assert archive.getinfo("show.json").compress_type == zipfile.ZIP_DEFLATED
    show = read_show(data)
    assert show["version"] == 1
    assert show["environment"] == {"type": "outdoor"}
    scenario, limits = circle.scenario, circle.scenario.limits
    assert show["meta"]["title"] == scenario.name and show["meta"]["id"] == "m1"
    assert show["meta"]["segments"] == {"show": [0.0, pytest.approx(scenario.horizon)]}
    validation = show["settings"]["validation"]
    assert validation["maxAltitude"] == pytest.approx(limits.position_max[2], abs=1e-3)
    assert validation["minDistance"] == pytest.approx(scenario.min_separation, abs=1e-3)
    assert validation["minDistance"] <= scenario.min_separation
    vx, vy, vz = limits.velocity_max
    assert validation["maxVelocityXY"] >= math.hypot(vx, vy)
    assert validation["maxVelocityXY"] == pytest.approx(math.hypot(vx, vy), abs=1e-3)
    assert validation["maxVelocityZ"] == pytest.approx(vz, abs=1e-3)
    fence = show["settings"]["geofence"]
    assert fence["version"] == 1 and len(fence["polygons"]) == 1
    polygon = fence["polygons"][0]
    assert polygon["isInclusion"] is True
    corners = np.array(polygon["points"])[:, :2]
    lo, hi = limits.position_min, limits.position_max
    assert {tuple(c) for c in corners.tolist()} == {
        (lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])}
    assert "cues" not in show["settings"]  # a plain plan has no formations
    drones = show["swarm"]["drones"]
    assert [d["settings"]["name"] for d in drones] == scenario.ids
    for drone, track in zip(drones, circle.vehicles, strict=True):
        assert drone["type"] == "generic"
        settings = drone["settings"]
        np.testing.assert_allclose(settings["home"], track.position[0], atol=1e-6)
        trajectory = settings["trajectory"]
        assert trajectory["version"] == 1
        assert trajectory["takeoffTime"] == 0
        first = trajectory["points"][0]
        assert first[0] == 0 and first[1] == settings["home"] and first[2] == []
        assert trajectory["points"][-1][0] == pytest.approx(scenario.horizon)
        assert trajectory["landingHeight"] == pytest.approx(track.position[-1][2], abs=1e-6)
        lights = settings["lights"]
        assert lights["version"] == 1 and base64.b64decode(lights["data"]) == b"\x00"
    assert b"NaN" not in data and b"Infinity" not in data


def test_a_sequence_names_its_formations_as_cues(sequence: Plan) -> None:
    cues = read_show(_export(sequence))["settings"]["cues"]
    assert cues["version"] == 1
    assert [c["name"] for c in cues["items"]] == ["grid", "sphere", "grid"]
    legs = [s for s in sequence.sequence["timeline"] if s["kind"] == "leg"]
    assert [c["time"] for c in cues["items"]] == [0.0] + [s["end_s"] for s in legs]


def test_the_same_plan_gives_the_same_bytes(circle: Plan) -> None:
    assert _export(circle) == _export(circle)
    assert SKYC_MEDIA_TYPE == "application/zip"


def test_an_origin_locates_the_show_with_its_x_axis_east(circle: Plan) -> None:
    origin = parse_origin("47.4979, 19.0402, 105.5")
    show = read_show(_export(circle, origin=origin))
    assert show["environment"]["location"] == {
        "origin": [474979000, 190402000, 105500], "orientation": SHOW_ORIENTATION_DEG}
    no_altitude = read_show(_export(circle, origin=parse_origin("-33.8,151.2")))
    assert no_altitude["environment"]["location"]["origin"] == [-338000000, 1512000000]


def test_the_show_frame_is_east_north_up() -> None:
    """Skybrush's "nwu" frame with its x axis at heading h (degrees from north towards east)
    and y 90 degrees to the left of x: with h = 90, a world (ENU) point keeps its east, north
    and height."""
    assert SHOW_AXES == "nwu"
    h = math.radians(SHOW_ORIENTATION_DEG)
    x_axis = np.array([math.sin(h), math.cos(h)])     # (east, north) of the show's x
    y_axis = np.array([-math.cos(h), math.sin(h)])    # x turned 90 degrees to the left
    rng = np.random.default_rng(3)
    world = rng.uniform(-50, 50, (20, 3))
    show = world_to_show(world)
    east_north = show[:, :1] * x_axis + show[:, 1:2] * y_axis
    np.testing.assert_allclose(east_north, world[:, :2], atol=1e-12)
    np.testing.assert_array_equal(show[:, 2], world[:, 2])


@pytest.mark.parametrize(
    ("text", "reason"),
    [("47.5", "LAT,LON"), ("a,b", "numbers"), ("95,10", "latitude"), ("10,200", "longitude"),
     ("10,20,1e9", "altitude"), ("nan,1", "finite"), ("1,2,3,4", "LAT,LON")],
)
def test_a_bad_origin_is_refused_naming_it(text: str, reason: str) -> None:
    with pytest.raises(ExportError, match=reason) as caught:
        parse_origin(text)
    assert caught.value.field == "origin"


def test_a_step_skybrush_cannot_time_is_refused(circle: Plan) -> None:
    odd = dataclasses.replace(circle, scenario=dataclasses.replace(circle.scenario, dt=0.0125))
    with pytest.raises(ExportError, match="whole number of milliseconds") as caught:
        check_exportable(odd)
    assert caught.value.field == "scenario.dt"
    with pytest.raises(ExportError):
        skyc_chunks(odd)  # refused before the first piece, not halfway through a download
    empty = dataclasses.replace(circle, vehicles=())
    with pytest.raises(ExportError, match="no trajectories"):
        check_exportable(empty)
