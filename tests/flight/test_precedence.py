"""gcs.flight.run.precedence: which of two conflicting commands wins, in the table and in a flight
on mock vehicles (a land overrides a hold under way; a hold, pause or replan is refused while
the fleet lands; every accepted command leaves an event, every refused one too)."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest

from gcs.autopilot import px4
from gcs.cli.control import ControlServer, request
from gcs.errors import FlightAborted, StateConflict
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.run.precedence import abort_in_force
from gcs.sim import MockFleet
from tests.flight.support import short_line, smooth_plan
from tests.flight.test_executor import _fly

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize(("current", "action", "in_force"), [
    (None, "hold", "hold"), (None, "land", "land"), ("hold", "land", "land"),
    ("hold", "hold", "hold"), ("land", "land", "land")])
def test_the_stronger_abort_is_in_force(current: str | None, action: str,
                                        in_force: str) -> None:
    assert abort_in_force(current, action) == in_force


def test_a_hold_after_a_land_is_refused_with_the_reason() -> None:
    with pytest.raises(StateConflict) as refused:
        abort_in_force("land", "hold", "operator abort")
    assert refused.value.field == "action"
    assert refused.value.reason == ("the flight is already aborting with land (operator "
                                    "abort): land overrides hold")
    with pytest.raises(ValueError, match="kill"):
        abort_in_force(None, "kill")


async def _while_flying(flight: FlightExecutor) -> None:
    while (flight.flight_time() or -1.0) < 0.3:
        await asyncio.sleep(0.02)


@pytest.mark.flight
def test_land_after_hold_lands_the_fleet() -> None:
    """A hold, then a land before the hold was answered: both are applied in that order
    (the land once the hold is sent), each with its event; a pause or replan now is refused
    naming the abort; the fleet ends landed and disarmed."""
    plan = smooth_plan(short_line(2, steps=30))
    refusals: list[str] = []

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        await _while_flying(flight)
        hold = asyncio.ensure_future(flight.abort("hold", "operator hold"))
        await asyncio.sleep(0)
        await flight.abort("land", "operator land")
        await hold
        for command in (flight.pause, lambda: flight.resume()):
            with pytest.raises(StateConflict) as refused:
                command()
            refusals.append(refused.value.reason)
        with pytest.raises(StateConflict) as refused:
            await flight.replan({"uav1": [0.0, 0.0, 1.0]})
        refusals.append(refused.value.reason)

    flight, outcome, mock = asyncio.run(_fly(plan, during=during))
    assert isinstance(outcome, FlightAborted)
    events = flight.recorder.events
    aborts = [e["detail"] for e in events if e["kind"] == "abort"]
    assert aborts[0] == "operator hold: hold all"
    assert aborts[1].startswith("operator land: land all (overrides the hold of operator hold")
    assert refusals == [f"the flight is aborting (land): an abort overrides {c}"
                        for c in ("pause", "resume", "replan")]
    kinds = [(e["vehicle"], e["kind"]) for e in events]
    for v in plan.scenario.ids:  # held first, then landed
        assert kinds.index((v, "hold")) < kinds.index((v, "land"))
    for vehicle in mock.vehicles:
        assert not vehicle.armed
        assert vehicle.position_ned[2] == pytest.approx(0.0, abs=0.05)


@pytest.mark.flight
def test_hold_after_land_is_refused_and_recorded() -> None:
    """A hold while the fleet lands is refused with the reason (and a `command_refused`
    event); a repeated land is accepted and changes nothing (its own event)."""
    plan = smooth_plan(short_line(2, steps=30))
    refused: list[StateConflict] = []

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        await _while_flying(flight)
        land = asyncio.ensure_future(flight.abort("land", "operator land"))
        await asyncio.sleep(0)
        try:
            await flight.abort("hold", "operator hold")
        except StateConflict as exc:
            refused.append(exc)
        await flight.abort("land", "operator land again")
        await land

    flight, outcome, mock = asyncio.run(_fly(plan, during=during))
    assert isinstance(outcome, FlightAborted)
    assert [exc.reason for exc in refused] == [
        "the flight is already aborting with land (operator land): land overrides hold"]
    events = flight.recorder.events
    assert [e["detail"] for e in events if e["kind"] == "command_refused"] == [
        "operator hold: hold all: the flight is already aborting with land (operator land): "
        "land overrides hold"]
    assert [e["detail"] for e in events if e["kind"] == "abort"] == [
        "operator land: land all",
        "operator land again: land all (already under way: operator land)"]
    assert not any(v.mode == px4.HOLD for v in mock.vehicles)
    assert not any(vehicle.armed for vehicle in mock.vehicles)


class _Socketed:
    """`gcs.cli.control.Flight` on a flight executor, as `fleetplan fly --control` drives
    one (through its `FlightHandle`)."""

    def __init__(self, flight: FlightExecutor) -> None:
        self.flight = flight

    async def replan(self, goals: Any, drop: list[str], drop_action: str,
                     reason: str) -> dict[str, Any]:
        return await self.flight.replan(goals, drop, drop_action, reason)

    async def pause(self) -> float:
        return self.flight.pause()

    async def resume(self) -> float:
        return self.flight.resume()

    async def abort(self, action: str = "land", reason: str = "operator abort") -> None:
        await self.flight.abort(action, reason)


@pytest.mark.flight
def test_racing_aborts_over_the_control_socket(tmp_path: Path) -> None:
    """Hold and land sent together over `fly`'s control socket: the land is answered ok
    whatever came first; the hold is applied before it or refused with the reason."""
    plan = smooth_plan(short_line(2, steps=30))
    answers: list[dict[str, Any]] = []

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        server = ControlServer(tmp_path / "fly.sock", _Socketed(flight), 2)
        await server.start()
        try:
            await _while_flying(flight)
            answers.extend(await asyncio.gather(
                request(server.path, {"command": "abort", "action": "hold"}),
                request(server.path, {"command": "abort", "action": "land"})))
        finally:
            await server.close()

    flight, outcome, mock = asyncio.run(_fly(plan, during=during))
    assert isinstance(outcome, FlightAborted)
    hold, land = answers
    assert land == {"ok": True}
    assert hold == {"ok": True} or hold["error"]["reason"].endswith("land overrides hold")
    aborts = [e["detail"] for e in flight.recorder.events if e["kind"] == "abort"]
    assert len(aborts) == (2 if hold["ok"] else 1)
    assert not any(vehicle.armed for vehicle in mock.vehicles)
