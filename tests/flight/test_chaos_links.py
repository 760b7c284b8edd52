"""Faulty radio links between the station and the mocks (`gcs.sim.proxy`), short cases of
the chaos benchmark (`bench/chaos.py`): a link that only jitters (100-300 ms, nothing lost)
passes the pre-flight gate, its reordering counted apart from loss; 20 % loss that starts
after take-off is told as a `link_degraded` event with its figures and kept in the record."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.run.executor import FlightExecutor
from gcs.phases import EventKind
from gcs.sim import MockFleet, homes_under
from gcs.sim.proxy import ChaosProxy, LinkFaults
from tests.flight.support import FAST_MOCK, QUICK, short_line, smooth_plan
from tests.support.waiting import until

pytestmark = [pytest.mark.flight, pytest.mark.timeout(150)]


async def _fly_through(plan: Any, options: FlightOptions, faults: LinkFaults,
                       after_takeoff: LinkFaults | None = None
                       ) -> tuple[FlightExecutor, Any, ChaosProxy]:
    """Fly `plan` on mocks whose links all pass a `ChaosProxy` with `faults`, then (once
    the flight clock runs) `after_takeoff`."""
    homes = homes_under(plan.scenario.starts)
    proxy, ports = ChaosProxy.on_free_ports(len(homes), seed=7, faults=faults)
    async with proxy, MockFleet(homes=homes, settle_time=0.5, **ports, **FAST_MOCK) as mock:
        fleet = FleetSpec.from_dict(proxy.fleet_dict(mock.fleet_dict(plan.scenario.ids)))
        flight = FlightExecutor(plan, fleet, options)
        task = flight.start()
        if after_takeoff is not None:
            await until(lambda: task.done() or (flight.flight_time() or -1.0) >= 0.2,
                        "flight time 0.2 s or the flight's end", timeout=90.0, poll=0.02)
            proxy.set(None, **vars(after_takeoff))
        try:
            outcome: Any = await task
        except Exception as exc:
            outcome = exc
        return flight, outcome, proxy


def test_a_jittery_link_without_loss_passes_the_gate() -> None:
    plan = smooth_plan(short_line(2, steps=20))
    options = QUICK.replace(tracking_error_max=3.0, link_timeout=3.0)
    flight, outcome, proxy = asyncio.run(_fly_through(plan, options,
                                                      LinkFaults(delay=0.1, jitter=0.2)))
    assert flight.record is not None
    kinds = [(e["vehicle"], e["kind"]) for e in flight.record["events"]]
    assert "PreflightFailed" not in repr(outcome)
    assert all((vid, EventKind.ARMED) in kinds for vid in plan.scenario.ids), kinds
    for vid in plan.scenario.ids:
        quality = flight.record["summary"]["link_quality"][vid]
        assert quality["reordered"] > 0  # the jitter did reorder them ...
        assert quality["loss_pct"] < 2.0, quality  # ... and nothing was lost
        assert quality["latency_ms"] >= 100.0  # bound: TIMESYNC's round trip, both ways
    assert all(proxy.counts(i).up_dropped == 0 for i in range(2))


def test_loss_after_takeoff_is_told_as_a_degraded_link() -> None:
    plan = smooth_plan(short_line(2, steps=40))  # 8 s of plan: time for the judgement
    options = QUICK.replace(tracking_error_max=3.0, link_timeout=3.0)
    flight, _outcome, proxy = asyncio.run(_fly_through(plan, options, LinkFaults(),
                                                       after_takeoff=LinkFaults(loss=0.2)))
    assert flight.record is not None
    degraded = [e for e in flight.record["events"] if e["kind"] == EventKind.LINK_DEGRADED]
    assert {e["vehicle"] for e in degraded} == set(plan.scenario.ids), degraded
    assert len(degraded) == 2  # once each: no flapping
    for event in degraded:
        loss = int(event["detail"].split("loss ")[1].split("%")[0])
        assert 10 <= loss <= 35, event["detail"]
    quality = flight.record["summary"]["link_quality"]
    assert all(quality[vid]["lost"] > 0 for vid in plan.scenario.ids)
    assert all(proxy.counts(i).up_dropped > 0 for i in range(2))
