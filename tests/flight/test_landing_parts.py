"""gcs.flight.safety.landing without sockets: which vehicles a landing plan steers, its switch, and
the fallbacks to PX4's Land (a vehicle out of reach, no plan in time)."""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest

import gcs.flight.safety.landing as landing_module
from gcs.autopilot import px4
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.link.setpoints import SetpointTrack, hold_track, plan_tracks
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.safety.landing import PlannedLanding
from gcs.flight.timeline.clock import FlightClock
from gcs.flight.timeline.flown import FlownPlans
from gcs.flight.timeline.stream import Streamer
from gcs.phases import EventKind, VehiclePhase
from planner.methods.landing import LandingError, plan_landing
from planner.model.scenario import Scenario
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


def _setup(points=POINTS) -> tuple[list[VehicleStatus], Streamer,
                                    list[tuple[str | None, str, str]], list[str]]:
    """Two fake vehicles (homes at the origin) streaming holds at `points` (world)."""
    streamer = Streamer(20.0)
    vehicles = []
    for i, point in enumerate(points):
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

    return PlannedLanding(SCENARIO, vehicles, streamer, _context(events, **options), secure)


def _context(events, **options) -> FlightContext:
    """A flight's context whose events go to `events`."""
    return FlightContext(FlightOptions(**options),
                         lambda vid, kind, detail: events.append((vid, kind, detail)))


def _slow(seconds: float):
    """A planner that takes `seconds` and then fails."""
    def slow(*args, **kwargs):
        time.sleep(seconds)
        raise LandingError("too late to matter")

    return slow


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
    monkeypatch.setattr(landing_module, "plan_landing", _slow(0.6))
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


def test_the_flying_plan_streams_until_the_switch_tick_then_the_landing_plan() -> None:
    """While the landing plan waits for its switch tick the vehicle flies on along its
    flying plan (here 1 m/s north), setpoint for setpoint; the first one after is the landing
    plan's first, moving on at the same velocity (not its switch point at rest, early)."""
    vehicles, streamer, events, secured = _setup()
    rate = streamer.rate
    ticks = np.arange(int(10 * rate))[:, None] / rate
    start = np.array([POINTS[0][1], POINTS[0][0], -POINTS[0][2]])  # NED
    north = np.array([[1.0, 0.0, 0.0]])
    flying = SetpointTrack(start + ticks * north, np.repeat(north, len(ticks), axis=0),
                           np.zeros((len(ticks), 3)), 0.0, rate)
    sent: list[tuple[int, tuple]] = []
    streamer.listeners.append(
        lambda vid, tick, sp, _: sent.append((tick, sp)) if vid == "uav1" else None)
    landing = _landing(vehicles, streamer, events, secured, landing_plan_timeout=1.0)

    async def fly() -> tuple[int, int]:
        streamer.start()
        began = streamer.assign("uav1", vehicles[0].linked, flying)
        await asyncio.sleep(0.2)
        # the tick the landing starts from (not a tick counted from `began`: a loaded
        # machine may send no setpoint for a while, and the streamer skips those ticks)
        aborted = streamer.next_tick()
        await landing.run()
        await streamer.stop()
        return began, aborted

    began, aborted = asyncio.run(fly())
    assert landing.result is not None, events
    landing_track = plan_tracks(landing.result.plan, [v.placed for v in vehicles], rate)[0]
    first = landing_track.at(0)
    assert first.velocity[0] == pytest.approx(1.0, abs=1e-6)
    switch = next(t for t, sp in sent if sp != flying.at(t - began))
    assert switch - aborted >= rate  # the whole landing_plan_timeout on the flying plan
    assert all(sp == flying.at(t - began) for t, sp in sent if t < switch)
    after = dict(sent)[switch]
    np.testing.assert_allclose(after.position, first.position, atol=1e-9)
    np.testing.assert_allclose(after.velocity, first.velocity, atol=1e-9)


#: Two vehicles 4 mm apart: no landing separation (R less what they have) is possible.
TOUCHING = [(2.0, 2.0, 1.5), (2.004, 2.0, 1.5)]


def _broken(*args, **kwargs):
    raise RuntimeError("solver crashed")


@pytest.mark.parametrize(("points", "planner", "reason"), [
    (TOUCHING, None, "too close to plan a landing"),
    (POINTS, _broken, "RuntimeError: solver crashed"),
])
def test_any_planning_failure_falls_back_naming_it(monkeypatch, points, planner,
                                                   reason: str) -> None:
    """Vehicles too close for any landing plan, or an unexpected error of the planner: a
    landing_fallback naming why, both landed by PX4's Land (the error does not escape and
    strand them streaming)."""
    if planner is not None:
        monkeypatch.setattr(landing_module, "plan_landing", planner)
    vehicles, streamer, events, secured = _setup(points)
    landing = _landing(vehicles, streamer, events, secured)
    asyncio.run(landing.run())
    fallbacks = [detail for _, kind, detail in events if kind == EventKind.LANDING_FALLBACK]
    assert len(fallbacks) == 1 and reason in fallbacks[0]
    assert sorted(secured) == ["uav1", "uav2"]


def test_a_cancelled_landing_still_lands_everyone(monkeypatch) -> None:
    """Cancelled while planning (the service stopping), the landing still hands every
    vehicle to PX4's Land."""
    monkeypatch.setattr(landing_module, "plan_landing", _slow(0.3))
    vehicles, streamer, events, secured = _setup()
    landing = _landing(vehicles, streamer, events, secured, landing_plan_timeout=1.0)

    async def cancel() -> None:
        task = asyncio.create_task(landing.run())
        await asyncio.sleep(0.1)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task

    asyncio.run(cancel())
    assert sorted(secured) == ["uav1", "uav2"]


def test_a_lost_vehicle_is_planned_around_and_a_failed_plan_holds_and_retries(
        monkeypatch) -> None:
    """uav2 is lost (unheard for 2 s, on its own failsafe: 1 s on, 0.5 s hold, Land): it is
    not sent PX4's Land but predicted, and the landing plan keeps clear of that motion. The
    first attempt fails (refused here at every share of the margin, landing or moving
    away first): uav1 holds where it is
    and the landing is planned again from there; uav1, 0.6 m from uav2 as it starts, keeps
    what it has from uav2 alone, back to R within seconds; uav2 is handed to Land only once
    its motion has ended."""
    calls: list[int] = []

    def first_fails(*args, **kwargs):
        calls.append(len(kwargs["fixed"]))
        if len(calls) <= len(landing_module.MARGIN_SHARES) * len(landing_module.STAGES):
            raise LandingError("no room yet")
        return plan_landing(*args, **kwargs)

    monkeypatch.setattr(landing_module, "plan_landing", first_fails)
    vehicles, streamer, events, secured = _setup()
    lost = vehicles[1]
    lost.fault, lost.phase = "link_lost", VehiclePhase.FAULTY
    lost.failsafe = px4.OffboardLossFailsafe(1.0, 0.5, px4.OBL_LAND)
    tel = lost.linked.telemetry
    heard = time.monotonic() - 2.0
    tel.position_ned, tel.velocity_ned = (POINTS[1][1], POINTS[1][0], -POINTS[1][2]), (0, 0, 0)
    tel.position_time = tel.message_time = heard
    clock = FlightClock(streamer.rate, streamer.epoch, streamer.epoch)
    clock.begin(0)
    flown = FlownPlans([])
    landing = PlannedLanding(SCENARIO, vehicles, streamer,
                             _context(events, landing_plan_timeout=0.5),
                             lambda v: _secure(v, streamer, secured), flown, clock)

    async def fly() -> None:
        streamer.start()
        await landing.run()
        await streamer.stop()

    asyncio.run(fly())
    told = [(vid, kind, detail) for vid, kind, detail in events]
    assert ("uav2", EventKind.LANDING_FALLBACK) in [(v, k) for v, k, _ in told]
    [held] = [d for v, k, d in told if k == EventKind.LANDING_FALLBACK and v is None]
    assert held.startswith("uav1 hold where they are: ") and "around uav2" in held
    [planned] = [d for _, k, d in told if k == EventKind.LANDING_PLAN]
    assert "around uav2" in planned and "started nearer than R: uav1 from uav2" in planned
    assert calls[:4] == [1, 1, 1, 1]  # every try planned around uav2's predicted motion
    assert landing.result is not None and landing.result.plan.scenario.ids == ["uav1"]
    [around] = landing.result.plan.scenario.fixed
    assert around.id == "uav2" and 0.0 < around.start_clearance["uav1"] < 1.0
    motion = flown.motions["uav2"]  # from its last report, what the monitor reads too
    assert motion.start == pytest.approx(heard - streamer.epoch, abs=0.05)
    assert secured == ["uav1", "uav2"]  # the lost one last, once its motion had ended
    assert clock.flight_time() >= motion.end


async def _secure(v: VehicleStatus, streamer: Streamer, secured: list[str]) -> None:
    secured.append(v.id)
    streamer.unassign(v.id)
