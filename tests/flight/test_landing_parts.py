"""gcs.flight.landing without sockets: which vehicles a landing plan steers, its switch, and
the fallbacks to PX4's Land (a vehicle out of reach, no plan in time)."""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest

import gcs.flight.landing as landing_module
from gcs.flight.fleetfile import FlightOptions
from gcs.flight.landing import PlannedLanding
from gcs.flight.phases import EventKind, VehiclePhase
from gcs.flight.setpoints import hold_track
from gcs.flight.station import StationStalls
from gcs.flight.stream import Streamer
from gcs.flight.vehicle import VehicleStatus
from planner.scenario import Scenario
from tests.flight.fakes import fake_vehicle

pytestmark = pytest.mark.timeout(60)

#: Two vehicles stacked 0.84 m apart vertically and 0.55 m horizontally.
POINTS = [(2.0, 2.0, 1.08), (2.55, 2.0, 1.92)]
SCENARIO = Scenario.from_dict({
    "dt": 0.2, "steps": 10, "min_separation": 1.0,
    "limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [5.0, 5.0, 3.0],
               "velocity_max": [2.0, 2.0, 2.0], "acceleration_max": [3.0, 3.0, 3.0]},
    "vehicles": [{"id": "uav1", "start": list(POINTS[0]), "goal": [2.0, 4.0, 1.08]},
                 {"id": "uav2", "start": list(POINTS[1]), "goal": [2.55, 4.0, 1.92]}],
})


def _setup() -> tuple[list[VehicleStatus], Streamer, list[tuple[str | None, str, str]],
                      list[str]]:
    """Two fake vehicles (homes at the origin) streaming holds at the stacked points."""
    streamer = Streamer(20.0)
    vehicles = []
    for i, point in enumerate(POINTS):
        v = fake_vehicle(i)
        v.phase = VehiclePhase.FLYING
        ned = (point[1], point[0], -point[2])  # ENU -> NED about a home at the origin
        streamer.assign(v.id, v.linked, hold_track(ned, 0.0, streamer.rate))
        vehicles.append(v)
    return vehicles, streamer, [], []


def _landing(vehicles, streamer, events, secured, **options) -> PlannedLanding:
    async def secure(v: VehicleStatus) -> None:
        secured.append(v.id)
        streamer.unassign(v.id)

    return PlannedLanding(SCENARIO, vehicles, streamer, FlightOptions(**options),
                          lambda vid, kind, detail: events.append((vid, kind, detail)),
                          secure, StationStalls())


def test_a_vehicle_out_of_reach_gets_px4_land_the_other_flies_the_plan() -> None:
    """A vehicle whose link went silent cannot fly setpoints: PX4's Land at once, said by a
    landing_fallback event; the other flies a verified landing plan from its state at the
    switch tick to a touchdown point, then is handed to PX4's Land."""
    vehicles, streamer, events, secured = _setup()
    vehicles[1].linked.telemetry.message_time = time.monotonic() - 10.0
    landing = _landing(vehicles, streamer, events, secured, landing_plan_timeout=1.0)
    assert [v.id for v in landing.eligible()] == ["uav1"]
    asyncio.run(landing.run())
    kinds = [(vid, kind) for vid, kind, _ in events]
    assert ("uav2", EventKind.LANDING_FALLBACK) in kinds
    assert (None, EventKind.LANDING_PLAN) in kinds
    assert sorted(secured) == ["uav1", "uav2"]
    assert landing.result is not None and landing.result.plan.ok
    planned = landing.result.plan
    assert planned.scenario.ids == ["uav1"]
    # from where it was, at rest, down to the touchdown height
    np.testing.assert_allclose(planned.scenario.starts[0], POINTS[0], atol=1e-9)
    assert planned.scenario.goals[0][2] == pytest.approx(FlightOptions().landing_height)
    assert vehicles[0].phase == VehiclePhase.LANDING


def test_no_plan_within_the_bound_falls_back_to_px4_land(monkeypatch) -> None:
    """A landing plan not ready before its switch tick is not used: the streams freeze and
    every vehicle gets PX4's Land, which a landing_fallback event says."""
    def slow(*args, **kwargs):
        time.sleep(0.6)
        raise AssertionError("too late to matter")

    monkeypatch.setattr(landing_module, "plan_landing", slow)
    vehicles, streamer, events, secured = _setup()
    landing = _landing(vehicles, streamer, events, secured, landing_plan_timeout=0.1)
    asyncio.run(landing.run())
    fallbacks = [detail for vid, kind, detail in events if kind == EventKind.LANDING_FALLBACK]
    assert len(fallbacks) == 1 and "no landing plan within 0.1 s" in fallbacks[0]
    assert EventKind.LANDING_PLAN not in [kind for _, kind, _ in events]
    assert sorted(secured) == ["uav1", "uav2"]
    assert landing.result is None


def test_an_unplannable_landing_falls_back_naming_why() -> None:
    """A landing the planner cannot make (the touchdown height outside the workspace) is a
    fallback to PX4's Land with the planner's reason."""
    vehicles, streamer, events, secured = _setup()
    landing = _landing(vehicles, streamer, events, secured, landing_height=10.0)
    asyncio.run(landing.run())
    fallbacks = [detail for _, kind, detail in events if kind == EventKind.LANDING_FALLBACK]
    assert len(fallbacks) == 1 and "outside the workspace" in fallbacks[0]
    assert sorted(secured) == ["uav1", "uav2"]
