"""`fleetplan fleet land --plan`: a fleet left hovering by a lost station (the Hold failsafe
of vehicles whose columns meet) is landed by a landing plan from a new station, keeping R.

The mock vehicles run in this test's process; the first station is a `FlightExecutor` here
whose links are then blackholed both ways (a station lost), the second the `fleetplan fleet
land --plan` command in a child process."""

from __future__ import annotations

import asyncio
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from gcs.autopilot import px4
from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.run.executor import FlightExecutor
from gcs.sim import MockFleet
from tests.flight.support import FAST_MOCK, QUICK, STACKED, mock_ports, smooth_plan
from tests.flight.support import STACKED_HOMES as HOMES
from tests.support.waiting import every, reached, until

pytestmark = [pytest.mark.timeout(150), pytest.mark.flight]


async def _lose_then_land(tmp_path: Path) -> tuple[list[np.ndarray], MockFleet, str, int]:
    """Fly STACKED, lose the station 1 s into the plan, wait until both hover on their
    failsafe, land them by `fleet land --plan`; the true positions from the loss until
    both are disarmed, the mocks, the command's output and exit status."""
    plan = smooth_plan(STACKED)
    async with MockFleet(homes=HOMES, settle_time=0.5, **mock_ports(2), **FAST_MOCK) as mock:
        fleet = mock.fleet_dict(plan.scenario.ids)
        flight = FlightExecutor(plan, FleetSpec.from_dict(fleet), QUICK)
        task = flight.start()
        await reached(flight, 1.0)
        for v in mock.vehicles:
            v.faults.loss = 1.0
        truth: list[np.ndarray] = []

        sampler = asyncio.create_task(every(0.01, lambda: truth.append(
            np.array([v.true_position_world for v in mock.vehicles]))))
        await until(lambda: all(v.mode == px4.HOLD for v in mock.vehicles),
                    "both vehicles in Hold after the station's loss", timeout=30.0,
                    detail=lambda: [v.mode for v in mock.vehicles])
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        await asyncio.sleep(1.0)
        assert all(v.armed and v.in_air and v.mode == px4.HOLD for v in mock.vehicles)
        for v in mock.vehicles:
            v.faults.loss = 0.0
        (tmp_path / "plan.json").write_text(json.dumps(plan.to_dict()))
        (tmp_path / "fleet.json").write_text(json.dumps(
            {**fleet, "flight": {"hold_at_goal": 0.5, "prestream": 0.3}}))
        child = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "gcs.cli.main", "fleet", "land",
            "--plan", str(tmp_path / "plan.json"), "--fleet", str(tmp_path / "fleet.json"),
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT)
        out, _ = await asyncio.wait_for(child.communicate(), 90)
        await until(lambda: not any(v.armed for v in mock.vehicles),
                    "both vehicles landed and disarmed", timeout=60.0, detail=out.decode)
        sampler.cancel()
        assert child.returncode is not None
        return truth, mock, out.decode(), child.returncode


def test_a_hovering_fleet_is_landed_by_plan_apart(tmp_path: Path) -> None:
    truth, mock, out, status = asyncio.run(_lose_then_land(tmp_path))
    assert status == 0, out
    assert "low: in the air at" in out and "high: in the air at" in out, out
    assert "landing plan:" in out and "flight_start" in out
    for v in mock.vehicles:
        assert not v.armed and v.true_position_world[2] < 0.05
        assert "failsafe: Hold" in [e for _t, e in v.events]
    # they hovered, then landed side by side: R kept throughout (the plan's metric is 1:1:1)
    gaps = [float(np.linalg.norm(p[0] - p[1])) for p in truth]
    assert min(gaps) >= STACKED["min_separation"] - 0.05
    a, b = (v.true_position_world for v in mock.vehicles)
    assert np.linalg.norm(a[:2] - b[:2]) >= STACKED["min_separation"] - 0.05
