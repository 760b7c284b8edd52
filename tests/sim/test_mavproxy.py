"""MAVProxy (a third-party ground station, from PyPI in the test extras) talks to the mock as to
PX4: it connects, fetches every parameter, lists the empty mission and fence, sets a
parameter, arms and takes off with `takeoff 2`. Driven through its stdin without a display,
each step waiting for MAVProxy's own answer, every wait bounded."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from gcs.autopilot import px4
from gcs.sim import MockFleet
from gcs.sim.paramdefs import PX4_PARAMS
from tests.flight.support import mock_ports
from tests.sim.mavproxy import MavProxy as _MavProxy
from tests.support.waiting import until

pytest.importorskip("MAVProxy", reason="MAVProxy is in the test extras: make install")

pytestmark = pytest.mark.timeout(120)


def test_mavproxy_fetches_parameters_lists_missions_and_takes_off(tmp_path: Path) -> None:
    async def main() -> None:
        ports = mock_ports(1)
        async with MockFleet(1, settle_time=0.5, **ports) as mock:
            v = mock.vehicles[0]
            proxy = _MavProxy(f"udpin:127.0.0.1:{v.gcs_port}", tmp_path)
            try:
                await asyncio.to_thread(_connect_and_list, proxy)
                proxy.send("param set MIS_TAKEOFF_ALT 2")
                await until(lambda: v.config.takeoff_altitude == 2.0, "MIS_TAKEOFF_ALT set", 30.0)
                proxy.send("arm throttle")
                await asyncio.to_thread(proxy.expect, "COMPONENT_ARM_DISARM: ACCEPTED", 30.0)
                await until(lambda: v.armed, "armed", 30.0)
                proxy.send("takeoff 2")
                await asyncio.to_thread(proxy.expect, "NAV_TAKEOFF: ACCEPTED", 30.0)
                # MAVProxy's takeoff 2 (param7 = 2 m AMSL, as MAVProxy sends it) is raised to
                # MIS_TAKEOFF_ALT, which MAVProxy set to 2 m: the vehicle holds 2 m up
                await until(lambda: v.mode == px4.HOLD and v.in_air, "holding after takeoff", 30.0)
                assert v.armed and -v.position_ned[2] == pytest.approx(2.0, abs=0.2)
            finally:
                proxy.close()

    def _connect_and_list(proxy: _MavProxy) -> None:
        proxy.expect("online system 1", 30.0)
        proxy.send("param fetch")
        proxy.expect(f"Received {len(PX4_PARAMS)} parameters", 30.0)
        proxy.send("wp list")
        proxy.expect("Requesting 0 waypoints", 30.0)
        proxy.send("fence list")
        proxy.expect("Requesting 0 fence items", 30.0)

    asyncio.run(main())
