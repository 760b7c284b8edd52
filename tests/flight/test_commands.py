"""gcs.fleet.commands: fleet commands outside a flight, on mock vehicles left hovering by an
abort with hold (nothing in a flight is left to land them)."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable

import numpy as np
import pytest

from gcs.autopilot import px4
from gcs.errors import FlightAborted, InvalidRequest, StateConflict
from gcs.fleet.commands import fleet_command
from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import VehicleLink
from gcs.flight.run.executor import FlightExecutor
from gcs.sim import MockFleet, homes_under
from tests.flight.support import FAST_MOCK, QUICK, line_scenario, mock_ports, smooth_plan

pytestmark = [pytest.mark.timeout(120), pytest.mark.flight]

FAST = QUICK


async def _until(predicate: Callable[[], bool], timeout: float) -> bool:
    deadline = asyncio.get_running_loop().time() + timeout
    while not predicate():
        if asyncio.get_running_loop().time() > deadline:
            return False
        await asyncio.sleep(0.05)
    return True


async def _hovering_fleet(count: int,
                          then: Callable[[MockFleet, dict[str, VehicleLink]], Awaitable[None]]
                          ) -> None:
    """Fly a plan on `count` mocks, abort it with hold mid-flight (the vehicles hover in PX4
    Hold), then open the fleet's connections afresh and run `then(mock, links)`."""
    plan = smooth_plan(line_scenario(count))
    homes = homes_under(plan.scenario.starts)
    # RTL_RETURN_ALT 0: RTL returns at the height it flies (PX4's default climbs to 60 m first)
    async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(count),
                         rtl_return_altitude=0.0, **FAST_MOCK) as mock:
        fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
        executor = FlightExecutor(plan, fleet, FAST)
        task = executor.start()
        while (executor.flight_time() or -1.0) < 1.0:
            await asyncio.sleep(0.02)
        await executor.abort("hold", "operator abort")
        with pytest.raises(FlightAborted):
            await task
        # the flight is over and nothing flies it any more: the fleet hovers in Hold
        assert all(v.armed and v.in_air and v.mode == px4.HOLD for v in mock.vehicles)
        async with LinkHub() as hub:
            links = {s.id: await hub.add(s.id, s.connection, s.system_id)
                     for s in fleet.vehicles}
            for link in links.values():
                assert await link.wait_for(lambda t: t.heartbeat_time is not None
                                           and t.landed_state is not None, 5.0)
            await then(mock, links)


def test_a_fleet_left_hovering_by_a_hold_abort_can_be_landed() -> None:
    """Abort with hold, then: disarm refused in the air, terminate refused without confirm
    (nothing sent), land one vehicle, return the other to launch; both end disarmed on the
    ground, the second over its home."""

    async def then(mock: MockFleet, links: dict[str, VehicleLink]) -> None:
        with pytest.raises(StateConflict, match="in the air") as refused:
            await fleet_command(links, "disarm")
        assert refused.value.field == "force"
        with pytest.raises(InvalidRequest) as unconfirmed:
            await fleet_command(links, "terminate")
        assert unconfirmed.value.field == "confirm"
        with pytest.raises(InvalidRequest, match="uav9"):
            await fleet_command(links, "land", ["uav9"])
        assert all(v.armed and v.in_air for v in mock.vehicles)  # nothing was sent

        [landing] = await fleet_command(links, "land", ["uav1"])
        assert landing.done and landing.mode == "AUTO.LAND", landing
        assert mock.vehicles[0].mode == px4.LAND
        assert mock.vehicles[1].mode == px4.HOLD  # only the chosen vehicle
        [returning] = await fleet_command(links, "rtl", ["uav2"])
        assert returning.done and returning.mode == "AUTO.RTL", returning

        assert await _until(lambda: not any(v.armed for v in mock.vehicles), 30.0)
        for v in mock.vehicles:
            assert v.position_ned[2] == pytest.approx(0.0, abs=0.05)
        # RTL brought uav2 back over its home before landing
        np.testing.assert_allclose(mock.vehicles[1].position_ned[:2], [0.0, 0.0], atol=0.25)
        # a landed fleet (once its HEARTBEAT says so): land is done with nothing to send
        assert await _until(lambda: not any(lk.telemetry.armed for lk in links.values()), 3.0)
        outcomes = await fleet_command(links, "land")
        assert all(o.done and o.armed is False for o in outcomes)
        assert all("already disarmed" in o.detail for o in outcomes)

    asyncio.run(_hovering_fleet(2, then))


def test_forced_disarm_and_confirmed_termination_stop_the_motors() -> None:
    """The last resorts: a forced disarm in the air, and flight termination with confirm,
    both confirmed from HEARTBEAT (disarmed; MAV_STATE_FLIGHT_TERMINATION)."""

    async def then(mock: MockFleet, links: dict[str, VehicleLink]) -> None:
        [forced] = await fleet_command(links, "disarm", ["uav1"], force=True)
        assert forced.done and forced.armed is False, forced
        [terminated] = await fleet_command(links, "terminate", ["uav2"], confirm=True)
        assert terminated.done and terminated.armed is False, terminated
        assert mock.vehicles[1].terminated
        assert await links["uav2"].wait_for(
            lambda t: t.system_status == 8, 3.0)  # MAV_STATE_FLIGHT_TERMINATION
        # both fell to the ground
        assert await _until(lambda: all(v.position_ned[2] > -0.05 for v in mock.vehicles), 5.0)

    asyncio.run(_hovering_fleet(2, then))
