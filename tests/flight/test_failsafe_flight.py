"""The link-loss failsafe in whole flights on the mock (`gcs.flight.procedure.failsafe` run by
the executor): Hold for vehicles whose columns meet, a failsafe that cannot be set refuses
the flight unless the fleet opts out, and the parameters read before arming are put back
after the flight, completed or aborted."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

import pytest

from gcs.autopilot import px4
from gcs.errors import FailsafeNotSet, FlightAborted
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.hub import LinkHub
from gcs.flight.procedure.params import read_param
from gcs.flight.run.executor import FlightExecutor
from gcs.phases import EventKind
from gcs.sim import MockFleet, homes_under
from tests.flight.support import FAST_MOCK, QUICK, STACKED, mock_ports, short_line, smooth_plan
from tests.flight.support import STACKED_HOMES as HOMES
from tests.support.waiting import reached

pytestmark = [pytest.mark.timeout(120), pytest.mark.flight]

#: PX4's own values the mock starts with, which the flight changes and must put back.
OWN = {"COM_OBL_RC_ACT": 0.0, "COM_FAIL_ACT_T": px4.COM_FAIL_ACT_T_S}


async def _fly(plan: Any, options: FlightOptions = QUICK, *, homes: Any = None,
               configure: Callable[[MockFleet], None] | None = None,
               during: Callable[[FlightExecutor], Any] | None = None
               ) -> tuple[Any, MockFleet]:
    """Fly `plan` on mock vehicles; (the record or the exception, the mock)."""
    homes = homes_under(plan.scenario.starts) if homes is None else homes
    async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(len(homes)),
                         **FAST_MOCK) as mock:
        if configure is not None:
            configure(mock)
        flight = FlightExecutor(plan, FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids)),
                                options)
        task = flight.start()
        if during is not None:
            await during(flight)
        try:
            outcome: Any = await task
        except Exception as exc:
            outcome = exc
        return outcome, mock


def _kinds(record: dict[str, Any], kind: str) -> list[dict[str, Any]]:
    return [e for e in record["events"] if e["kind"] == kind]


def test_stacked_columns_hover_the_others_land_and_the_parameters_are_put_back() -> None:
    """STACKED puts high 0.55 m beside low: both get Hold (landing straight down would bring
    them 0.55 m apart), each told why before arming, recorded per vehicle; after the
    completed flight both vehicles have PX4's own values again, with an event each."""
    record, mock = asyncio.run(_fly(smooth_plan(STACKED), homes=HOMES))
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True
    told = {e["vehicle"]: e["detail"] for e in _kinds(record, EventKind.FAILSAFE)
            if "without the station" in e["detail"]}
    assert set(told) == {"low", "high"}
    assert "then Hold" in told["low"] and "0.55 m from high's" in told["low"]
    assert "landing under it" in told["low"] and "landing onto it" in told["high"]
    fleet = [e["detail"] for e in _kinds(record, EventKind.FAILSAFE) if e["vehicle"] is None]
    assert any("low, high hover" in d and "fleetplan fleet land --plan" in d for d in fleet)
    for v in record["vehicles"]:
        assert v["failsafe"]["action"] == "Hold" and v["failsafe"]["set"] is True
    restored = [e for e in _kinds(record, EventKind.FAILSAFE) if "restored" in e["detail"]]
    assert {e["vehicle"] for e in restored} == {"low", "high"}
    assert all("COM_OBL_RC_ACT 5 -> 0" in e["detail"] for e in restored)
    for v in mock.vehicles:
        assert v.params.value("COM_OBL_RC_ACT") == OWN["COM_OBL_RC_ACT"]
        assert v.params.value("COM_FAIL_ACT_T") == OWN["COM_FAIL_ACT_T"]


def test_columns_apart_land_and_an_aborted_flight_puts_the_parameters_back() -> None:
    """Three vehicles 3 m apart: every column keeps R, so each lands on its failsafe
    (COM_OBL_RC_ACT 4); an abort with land mid-flight still restores PX4's own values."""
    plan = smooth_plan(short_line(3, steps=40))
    flights: list[FlightExecutor] = []

    async def abort(flight: FlightExecutor) -> None:
        flights.append(flight)
        await reached(flight, 1.0)
        flight.request_abort("land", "test")

    outcome, mock = asyncio.run(_fly(plan, during=abort))
    assert isinstance(outcome, FlightAborted), outcome
    record = flights[0].record
    assert record is not None
    assert [v["failsafe"]["action"] for v in record["vehicles"]] == ["Land"] * 3
    for v in mock.vehicles:
        assert not v.armed
        assert v.params.value("COM_OBL_RC_ACT") == OWN["COM_OBL_RC_ACT"]
        assert v.params.value("COM_FAIL_ACT_T") == OWN["COM_FAIL_ACT_T"]
    said = [text for v in mock.vehicles for text in v.statustexts]
    assert not any("Failsafe" in text for text in said)


@pytest.mark.parametrize("fault", ["kept", "silent"])
def test_a_failsafe_that_cannot_be_set_refuses_the_flight(fault: str) -> None:
    """One vehicle keeps COM_OBL_RC_ACT (its PARAM_SET answered with the old value), or
    answers no parameter message at all: the flight fails before any vehicle is armed,
    naming the vehicle and the parameter."""
    def configure(mock: MockFleet) -> None:
        faults = mock.vehicles[1].faults
        if fault == "kept":
            faults.params_kept = frozenset({"COM_OBL_RC_ACT"})
        else:
            faults.params_silent = True

    plan = smooth_plan(short_line(3))
    outcome, mock = asyncio.run(_fly(plan, configure=configure))
    assert isinstance(outcome, FailsafeNotSet), outcome
    assert outcome.vehicle == plan.scenario.ids[1]
    assert outcome.parameter == ("COM_OBL_RC_ACT" if fault == "kept" else "COM_OF_LOSS_T")
    assert outcome.parameter in str(outcome) and "failsafe: try" in str(outcome)
    assert not any(v.armed or any(e == "armed" for _t, e in v.events) for v in mock.vehicles)


def test_a_fleet_that_opts_out_flies_a_vehicle_whose_failsafe_cannot_be_set() -> None:
    """Fleet option failsafe: try: the silent vehicle flies on its own parameters, and the
    event says so; the others' failsafes are set and put back."""
    def configure(mock: MockFleet) -> None:
        mock.vehicles[0].faults.params_silent = True

    plan = smooth_plan(short_line(2))
    record, mock = asyncio.run(_fly(plan, QUICK.replace(failsafe="try"), configure=configure))
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True
    first, second = plan.scenario.ids
    details = {e["vehicle"]: e["detail"] for e in _kinds(record, EventKind.FAILSAFE)
               if "restored" not in e["detail"]}
    assert details[first].startswith("not set (COM_OF_LOSS_T not answered")
    assert "without the station" in details[second]
    assert record["vehicles"][0]["failsafe"]["set"] is False
    assert mock.vehicles[1].params.value("COM_OBL_RC_ACT") == OWN["COM_OBL_RC_ACT"]


def test_parameters_are_read_over_a_lossy_link() -> None:
    """20 % of the datagrams lost each way (the chaos bench's lossy start): every one of 12
    reads is answered within its tries, so a lossy link does not refuse the flight."""
    async def main() -> list[float]:
        async with MockFleet(1, settle_time=0.2, seed=3, **mock_ports(1), **FAST_MOCK) as mock, \
                LinkHub() as hub:
            link = await hub.add("v0", mock.gcs_url(0), 1)
            assert await link.wait_for(lambda t: t.heartbeat_time is not None, 5.0)
            mock.vehicles[0].faults.loss = 0.2
            return [await read_param(link, "COM_OBL_RC_ACT", "i") for _ in range(12)]

    assert asyncio.run(main()) == [OWN["COM_OBL_RC_ACT"]] * 12
