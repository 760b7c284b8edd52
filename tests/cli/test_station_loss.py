"""A fleet that loses its ground station: `fleetplan fly` killed with SIGKILL mid-flight.

The mock vehicles run in this test's process, the station in a child process (`fleetplan
fly --fleet`), so killing the station leaves the vehicles flying on their own, with PX4's
timings: 1 s without setpoints, Position hold for COM_FAIL_ACT_T, then Land. Before arming,
the station set each vehicle's failsafe to land by altitude layer (lowest first); the true
separation, read from the mocks' own state, stays >= R - 0.05 m until every vehicle is on
the ground, and the record the station wrote as it went is readable.
"""

from __future__ import annotations

import asyncio
import json
import signal
import sys
from pathlib import Path

import numpy as np
import pytest

import planner
from gcs.autopilot import px4
from gcs.sim import MockFleet
from gcs.sim.fleet import homes_under
from tests.flight.support import FAST_MOCK, mock_ports
from tests.support.waiting import every, until

pytestmark = pytest.mark.timeout(150)

EXAMPLES = Path(__file__).resolve().parents[2] / "planner" / "examples"


def _layered_plan() -> planner.Plan:
    """paper-circle4 in 12 s, its two altitude layers (1.1 m and 1.9 m) kept apart in
    columns too (separation_scale [1, 1, 10]: every two vehicles nearly R apart
    horizontally), so that landing straight down from anywhere keeps R."""
    data = json.loads((EXAMPLES / "paper-circle4.json").read_text())
    plan = planner.plan(planner.Scenario.from_dict(
        {**data, "steps": 60, "separation_scale": [1.0, 1.0, 10.0]}))
    assert plan.ok, plan.problems()
    return plan


async def _kill_station_at(tmp_path: Path, plan: planner.Plan, at: float
                           ) -> tuple[list[np.ndarray], MockFleet, str]:
    """Fly `plan` from a `fleetplan fly` child, SIGKILL it `at` s after the plan started;
    every vehicle's true position until all are disarmed, the mocks, the child's output."""
    homes = homes_under(plan.scenario.starts)
    async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(len(homes)),
                         **FAST_MOCK) as mock:
        (tmp_path / "plan.json").write_text(json.dumps(plan.to_dict()))
        (tmp_path / "fleet.json").write_text(json.dumps(mock.fleet_dict(plan.scenario.ids)))
        child = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "gcs.cli.main", "fly", str(tmp_path / "plan.json"),
            "--fleet", str(tmp_path / "fleet.json"), "--hold-at-goal", "0.5",
            "--climb-speed", "2", "--prestream", "0.3",
            "--record", str(tmp_path / "record.json"),
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT)
        assert child.stdout is not None
        out: list[str] = []
        while line := (await asyncio.wait_for(child.stdout.readline(), 60)).decode():
            out.append(line)
            if "flight_start" in line:
                break
        await asyncio.sleep(at)
        child.send_signal(signal.SIGKILL)
        truth: list[np.ndarray] = []
        sampler = asyncio.create_task(every(0.01, lambda: truth.append(
            np.array([v.true_position_world for v in mock.vehicles]))))
        await until(lambda: not any(v.armed for v in mock.vehicles),
                    "every vehicle landed on its failsafe and disarmed", timeout=60.0,
                    poll=0.01)
        sampler.cancel()
        rest, _ = await child.communicate()
        assert child.returncode == -signal.SIGKILL
        return truth, mock, "".join(out) + rest.decode()


def _closest_airborne(truth: list[np.ndarray], scale: np.ndarray) -> float:
    """Smallest true pair distance (the plan's metric) while any vehicle is in the air."""
    i, j = np.triu_indices(truth[0].shape[0], k=1)
    return min(float(np.min(np.linalg.norm((p[i] - p[j]) / scale, axis=1)))
               for p in truth if np.any(p[:, 2] > 0.05))


@pytest.mark.flight
def test_a_killed_station_leaves_the_fleet_landing_apart_by_layer(tmp_path: Path) -> None:
    plan = _layered_plan()
    truth, mock, out = asyncio.run(_kill_station_at(tmp_path, plan, 4.0))
    # before arming, each vehicle was told what to do without the station, and it shows
    assert out.count("without the station: after 1 s without setpoints") == 4, out
    low = [n for n, v in enumerate(plan.scenario.vehicles) if v.start[2] < 1.5]
    high = [n for n in range(4) if n not in low]
    delays = [v.config.failsafe_action_delay for v in mock.vehicles]
    assert {delays[n] for n in low} == {px4.COM_FAIL_ACT_T_S}
    # the upper layer waits until the lower one (1.1 m at 0.7 m/s) has had time to land
    assert min(delays[n] for n in high) >= px4.COM_FAIL_ACT_T_S + 1.1 / 0.7
    for v in mock.vehicles:
        assert v.config.offboard_loss_action == px4.OBL_LAND and not v.armed
        assert v.true_position_world[2] < 0.05
    # each landed by its own failsafe, the lower layer first
    landed = {n: next(t for t, what in v.events if what == "failsafe: Land")
              for n, v in enumerate(mock.vehicles)}
    assert max(landed[n] for n in low) < min(landed[n] for n in high)
    assert len(truth) > 200  # every 10 ms of some 10 s (fewer on a busy machine)
    r = plan.scenario.min_separation
    assert _closest_airborne(truth, np.asarray(plan.scenario.separation_scale)) >= r - 0.05
    # the record so far, written as the flight went
    record = json.loads((tmp_path / "record.json").read_text())
    assert record["partial"] is True
    kinds = [e["kind"] for e in record["events"]]
    assert kinds.count("failsafe") >= 4 and "flight_start" in kinds
