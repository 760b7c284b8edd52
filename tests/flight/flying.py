"""Shared helpers of the flight tests: flying a plan on mock vehicles, streaming a setpoint, a
monitor on fake vehicles, the attacker process."""

from __future__ import annotations

import asyncio
import json
import sys
from collections.abc import Awaitable, Callable
from typing import Any

from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.link import VehicleLink
from gcs.flight.link.setpoints import Setpoint
from gcs.flight.link.station import StationStalls
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.safety.monitor import FleetMonitor
from gcs.sim import MockFleet, homes_under
from planner.result import Plan
from tests.flight.fakes import Findings
from tests.flight.support import (
    FAST_MOCK,
    QUICK,
    line_scenario,
    mock_ports,
    smooth_plan,
)
from tests.paths import ROOT
from tests.support.waiting import every

__all__ = ["ALL_ATTACKS", "FAST", "RATE_SCALE", "Attacker", "fly_on_mocks", "monitor_of",
           "stream_setpoint"]

#: The flight options of these flights (`tests.flight.support.QUICK`).
FAST = QUICK


async def fly_on_mocks(plan: Plan, options: FlightOptions = FAST, *, settle: float = 0.5,
                       configure: Callable[[MockFleet], None] | None = None,
                       during: Callable[[FlightExecutor, MockFleet], Awaitable[Any]] | None = None,
                       fleet_extra: dict[str, Any] | None = None,
                       **mock_kw: Any) -> tuple[FlightExecutor, Any, MockFleet]:
    """Fly `plan` on mock vehicles below its starts (`fleet_extra`: top-level keys added to
    their fleet file); returns (flight, record or exception, mock)."""
    homes = homes_under(plan.scenario.starts)
    async with MockFleet(homes=homes, settle_time=settle, **mock_ports(len(homes)),
                         **{**FAST_MOCK, **mock_kw}) as mock:
        if configure is not None:
            configure(mock)
        fleet = FleetSpec.from_dict({**mock.fleet_dict(plan.scenario.ids), **(fleet_extra or {})})
        flight = FlightExecutor(plan, fleet, options)
        task = flight.start()
        if during is not None:
            await during(flight, mock)
        try:
            outcome = await task
        except Exception as exc:
            outcome = exc
        return flight, outcome, mock


async def stream_setpoint(link: VehicleLink, setpoint: Setpoint, period: float = 0.05) -> None:
    """Send `setpoint` to `link` every `period` s until cancelled."""
    await every(period, lambda: link.send_setpoint(setpoint, 0))


def monitor_of(vehicles: list[VehicleStatus], faults: list[tuple[str, str, float]],
               stalls: StationStalls, options: FlightOptions | None = None) -> FleetMonitor:
    """A fault monitor of `vehicles` on a line plan, noting each fault in `faults`."""
    plan = smooth_plan(line_scenario(max(1, len(vehicles))))
    context = FlightContext(options or FlightOptions(), lambda *_: None, stalls)
    return FleetMonitor(vehicles, plan, context, Findings(faults=faults))


#: Every attack `tests/flight/attacker.py` knows.
ALL_ATTACKS = "heartbeat,hijack,ack,truncated,random,nan"
#: The attacker's rates scaled to a fifth (still about 850 datagrams/s at three vehicles):
#: each spoof and malformed datagram is judged alone, so the count exercises the same
#: checks, while the full rates flood the GCS's receive buffers on a busy machine (the
#: station and the in-process mock then stall, and the vehicles' own datagrams overflow:
#: a real link loss that the preflight gate rightly refuses).
RATE_SCALE = 0.2


class Attacker:
    """`tests/flight/attacker.py` (`module`) in its own process."""

    module = "tests.flight.attacker"

    def __init__(self, ports: list[int], systems: list[int], attacks: str = ALL_ATTACKS
                 ) -> None:
        self.args = ["--ports", ",".join(map(str, ports)),
                     "--systems", ",".join(map(str, systems)),
                     "--duration", "90", "--attacks", attacks,
                     "--rate-scale", str(RATE_SCALE)]
        self.proc: asyncio.subprocess.Process | None = None

    async def start(self) -> None:
        self.proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", self.module, *self.args, cwd=ROOT,
            stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE)
        assert self.proc.stdout is not None
        assert json.loads(await self.proc.stdout.readline()) == {"ready": True}

    async def stop(self) -> dict[str, Any]:
        assert self.proc is not None and self.proc.stdin is not None
        self.proc.stdin.close()
        out, _ = await asyncio.wait_for(self.proc.communicate(), 20)
        return json.loads(out.decode().strip().splitlines()[-1])
