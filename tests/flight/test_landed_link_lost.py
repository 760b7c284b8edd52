"""A vehicle that landed and disarmed and then went out of reach is told apart from one lost
in the air: its phase is `landed_link_lost` and the summary says so (not "hovering")."""

from __future__ import annotations

import asyncio
import time
from typing import Any

from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.procedure import endings
from gcs.flight.procedure.context import FlightContext
from gcs.phases import EventKind, VehiclePhase
from gcs.wire import mavlink
from tests.flight.fakes import fake_link, fake_vehicle

OPTIONS = FlightOptions(land_timeout=2.0, link_timeout=0.5)


def _wait(armed: bool, landed_state: int) -> tuple[Any, list[tuple[Any, str, str]]]:
    v = fake_vehicle(0)
    v.phase = VehiclePhase.LANDING
    tel = fake_link(v).telemetry
    tel.armed, tel.landed_state = armed, landed_state
    tel.message_time = tel.heartbeat_time = time.monotonic() - 3.0  # out of reach for 3 s
    events: list[tuple[Any, str, str]] = []
    asyncio.run(endings.wait_disarmed([v], FlightContext(OPTIONS, lambda *e: events.append(e))))
    return v, events


def test_landed_and_disarmed_when_last_heard_is_not_hovering() -> None:
    v, events = _wait(False, mavlink.MAV_LANDED_STATE_ON_GROUND)
    assert v.phase == VehiclePhase.LANDED_LINK_LOST
    assert [(kind, detail.split(" when ")[0]) for _, kind, detail in events] == [
        (EventKind.DISARM_UNCONFIRMED, "link lost: landed and disarmed")]
    assert "out of reach since" in events[0][2]


def test_lost_in_the_air_says_so() -> None:
    v, events = _wait(True, mavlink.MAV_LANDED_STATE_IN_AIR)
    assert v.phase == VehiclePhase.LANDING
    assert events[0][1] == EventKind.DISARM_UNCONFIRMED
    assert events[0][2].startswith("link lost: armed and in the air when last heard")
    assert events[0][2].endswith("cannot confirm that it landed and disarmed")
