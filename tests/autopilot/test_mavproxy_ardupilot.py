"""MAVProxy talks to the mock's ArduCopter personality as to ArduCopter: it connects, fetches
every parameter (4.7's names), switches to GUIDED, arms and takes off with `takeoff 2`."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from gcs.autopilot import ardupilot
from gcs.sim import MockFleet
from gcs.sim.arducopter_params import ARDUCOPTER_PARAMS
from tests.flight.support import mock_ports
from tests.sim.mavproxy import MavProxy as _MavProxy
from tests.support.waiting import until

pytest.importorskip("MAVProxy", reason="MAVProxy is in the test extras: make install")

pytestmark = pytest.mark.timeout(120)


def test_mavproxy_fetches_parameters_and_takes_off_in_guided(tmp_path: Path) -> None:
    async def main() -> None:
        async with MockFleet(1, settle_time=0.5, autopilots=["ardupilot"],
                             **mock_ports(1)) as mock:
            v = mock.vehicles[0]
            proxy = _MavProxy(f"udpin:127.0.0.1:{v.gcs_port}", tmp_path)
            try:
                await asyncio.to_thread(proxy.expect, "online system 1", 30.0)
                proxy.send("param fetch")
                await asyncio.to_thread(proxy.expect,
                                        f"Received {len(ARDUCOPTER_PARAMS)} parameters", 30.0)
                proxy.send("mode GUIDED")
                await until(lambda: v.mode == ardupilot.GUIDED, "GUIDED", timeout=30.0)
                proxy.send("arm throttle")
                await until(lambda: v.armed, "armed", timeout=30.0)
                proxy.send("takeoff 2")
                await until(lambda: v.in_air and -v.position_ned[2] > 1.8, "up 2 m",
                            timeout=30.0)
                assert v.mode == ardupilot.GUIDED
            finally:
                proxy.close()

    asyncio.run(main())
