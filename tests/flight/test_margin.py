"""gcs.flight.safety.margin and the margin in flight: a fleet's position_error, plans that keep
2 x it, fly refusing (or warning about) a plan short of it, and the summary's verdicts."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gcs.errors import FleetFileError, PlanRejected
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.procedure.context import FlightContext
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.run.summary import goal_tolerance
from gcs.flight.safety.margin import check_margin, scenario_for_fleet, separation_alarm_at
from gcs.flight.safety.monitor import FleetMonitor
from gcs.phases import VehiclePhase
from gcs.sim import MockFleet, homes_under
from planner import Scenario
from tests.flight.fakes import Findings, fake_vehicle
from tests.flight.support import (
    FAST_MOCK,
    QUICK,
    line_scenario,
    mock_ports,
    short_line,
    smooth_plan,
)

pytestmark = pytest.mark.timeout(120)


def _fleet(count: int, **top: object) -> FleetSpec:
    return FleetSpec.from_dict({"vehicles": [
        {"id": f"uav{i + 1}", "connection": f"udpin:127.0.0.1:{30000 + i}",
         "system_id": i + 1, "home": [0, 0, 0]} for i in range(count)], **top})


def test_scenario_for_fleet_adds_twice_the_error_and_states_it() -> None:
    base = line_scenario(2)
    planned = scenario_for_fleet(base, 0.25)
    assert base["min_separation"] == 1.0 and "separation_margin" not in base  # a copy
    assert planned["min_separation"] == pytest.approx(1.5)
    assert planned["separation_margin"] == pytest.approx(0.5)
    scenario = Scenario.from_dict(planned)
    assert scenario.separation_margin == pytest.approx(0.5)
    assert scenario.to_dict()["separation_margin"] == pytest.approx(0.5)
    # a scenario without a margin says nothing about it (no margin keys in its JSON)
    assert "separation_margin" not in Scenario.from_dict(base).to_dict()
    with pytest.raises(ValueError, match="separation_margin"):
        Scenario.from_dict({**base, "separation_margin": 1.0})


def test_fleet_file_position_error() -> None:
    assert _fleet(1).position_error is None
    assert _fleet(1, position_error=0.3).position_error == pytest.approx(0.3)
    assert _fleet(1, position_error=0.3).to_dict()["position_error"] == pytest.approx(0.3)
    for bad in (-0.1, "x", 50.0):
        with pytest.raises(FleetFileError) as err:
            _fleet(1, position_error=bad)
        assert err.value.field == "position_error"


def test_fly_refuses_a_plan_short_of_the_fleets_margin_unless_told_to_warn() -> None:
    plain = smooth_plan(line_scenario(2))
    fleet = _fleet(2, position_error=0.2)
    check = check_margin(plain, 0.2)
    assert not check.ok and check.needed == pytest.approx(0.4) and check.planned == 0.0
    with pytest.raises(PlanRejected, match=r"margin 0.00 m, the fleet needs 0.40 m"):
        FlightExecutor(plain, fleet)
    FlightExecutor(plain, fleet, FlightOptions(margin_check="warn"))  # flies, with a warning
    FlightExecutor(plain, _fleet(2))  # a fleet that states no error: nothing to check
    margined = smooth_plan(scenario_for_fleet(line_scenario(2), 0.2))
    assert check_margin(margined, 0.2).ok
    FlightExecutor(margined, fleet)


@pytest.mark.flight
def test_a_flight_with_a_margin_reports_separation_against_r_and_why_it_completed() -> None:
    """Planned for position_error 0.15 m (R 1 m -> 1.3 m): the summary judges the goals with
    max(0.2, 2 x 0.15) = 0.3 m, the separation flown against the 1 m the vehicles must keep,
    and says why the flight is complete."""
    plan = smooth_plan(scenario_for_fleet(short_line(2, spacing=1.5), 0.15))

    async def fly() -> dict:
        homes = homes_under(plan.scenario.starts)
        async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(2),
                             **FAST_MOCK) as mock:
            fleet = FleetSpec.from_dict({**mock.fleet_dict(plan.scenario.ids),
                                         "position_error": 0.15})
            executor = FlightExecutor(plan, fleet, QUICK)
            return await executor.run()

    record = asyncio.run(fly())
    summary = record["summary"]
    assert summary["completed"] is True, summary
    assert summary["goal_tolerance"] == pytest.approx(0.3)
    # per vehicle: the mock reports h_acc 0.05 m, below the fleet's 0.15 m
    assert summary["goal_tolerances"] == {"uav1": pytest.approx(0.3), "uav2": pytest.approx(0.3)}
    assert summary["min_separation_required"] == pytest.approx(1.0)
    assert summary["separation_held"] is True
    assert summary["separation_margin"] == {"planned": pytest.approx(0.3),
                                            "needed": pytest.approx(0.3),
                                            "clearance": pytest.approx(1.0), "ok": True}
    assert summary["why"][0].startswith("complete: every vehicle within 0.30 m")
    assert record["events"][0]["kind"] == "margin"


def test_goal_tolerance_accounts_for_the_reported_accuracy() -> None:
    """max(configured, k x the larger of the fleet's position_error and the vehicle's h_acc):
    the SITL flight (goal errors up to 0.27 m) completes with a 0.25 m error."""
    opts = FlightOptions()
    assert goal_tolerance(opts, None) == pytest.approx(0.2)  # the fixed tolerance
    assert goal_tolerance(opts, None, 0.05) == pytest.approx(0.2)
    assert goal_tolerance(opts, 0.25) == pytest.approx(0.5)
    assert goal_tolerance(opts, 0.1, 0.4) == pytest.approx(0.8)
    assert goal_tolerance(opts.replace(goal_tolerance_k=1.0), 0.25, float("nan")) == \
        pytest.approx(0.25)


def test_plan_for_a_fleet_from_the_command_line(tmp_path: Path) -> None:
    scenario = tmp_path / "s.json"
    scenario.write_text(json.dumps(line_scenario(2, spacing=3.0)))
    fleet = tmp_path / "fleet.json"
    fleet.write_text(json.dumps({"vehicles": [{"id": "uav1", "connection": "udpin:h:1",
                                               "system_id": 1, "home": [0, 0, 0]}],
                                 "position_error": 0.25}))
    out = tmp_path / "plan.json"
    proc = subprocess.run([sys.executable, "-m", "gcs.cli.main", "plan", str(scenario),
                           "--fleet", str(fleet), "-o", str(out), "-q"],
                          capture_output=True, text=True, timeout=90)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "min_separation 1 m + 2 x 0.25 m = 1.5 m" in proc.stdout
    doc = json.loads(out.read_text())
    assert doc["scenario"]["min_separation"] == pytest.approx(1.5)
    assert doc["scenario"]["separation_margin"] == pytest.approx(0.5)
    fleet.write_text(json.dumps({"vehicles": [{"id": "uav1", "connection": "udpin:h:1",
                                               "system_id": 1, "home": [0, 0, 0]}]}))
    proc = subprocess.run([sys.executable, "-m", "gcs.cli.main", "plan", str(scenario),
                           "--fleet", str(fleet), "-o", str(out), "-q"],
                          capture_output=True, text=True, timeout=90)
    assert proc.returncode == 2 and "states no position_error" in proc.stderr


def test_the_alarm_sits_at_the_clearance_the_vehicles_must_keep() -> None:
    """Planned for R 1 m + a 0.5 m margin: the alarm line is R (not 1.5 m - 0.3 m = 1.2 m);
    without a margin it keeps the 0.3 m band below R; a stated band applies below R."""
    margin_plan = smooth_plan(scenario_for_fleet(short_line(2), 0.25))
    assert margin_plan.scenario.min_separation == pytest.approx(1.5)
    assert separation_alarm_at(margin_plan.scenario, None) == pytest.approx(1.0)
    assert separation_alarm_at(margin_plan.scenario, 0.1) == pytest.approx(0.9)
    bare = smooth_plan(short_line(2)).scenario
    assert separation_alarm_at(bare, None) == pytest.approx(0.7)
    assert separation_alarm_at(bare, 0.0) == pytest.approx(1.0)
    assert FlightOptions.from_dict({"separation_alarm": None}).separation_alarm is None
    assert FlightOptions.from_dict({"separation_alarm": 0}).separation_alarm == 0
    with pytest.raises(FleetFileError, match=r"flight\.separation_alarm"):
        FlightOptions.from_dict({"separation_alarm": -0.1})


def test_the_live_alarm_lets_a_flight_use_its_margin_and_stops_one_below_r() -> None:
    """The monitor on a margin plan (R 1 m, planned 1.5 m): two vehicles 1.1 m apart are in
    the margin and fly on; 0.95 m apart they are below R and the fleet is stopped."""
    plan = smooth_plan(scenario_for_fleet(short_line(2), 0.25))
    vehicles = [fake_vehicle(0), fake_vehicle(1)]
    for v in vehicles:
        v.phase = VehiclePhase.FLYING
    found = Findings()
    monitor = FleetMonitor(vehicles, plan, FlightContext(FlightOptions(), lambda *_: None),
                           found)
    for gap in (1.4, 1.2, 1.1, 1.001):
        monitor.check_separation({"uav1": np.zeros(3), "uav2": np.array([gap, 0.0, 0.0])})
    assert found.separations == []
    monitor.check_separation({"uav1": np.zeros(3), "uav2": np.array([0.95, 0.0, 0.0])})
    assert found.separations == [(pytest.approx(0.95), pytest.approx(1.0), "uav1 and uav2")]


def test_an_unheard_vehicle_counts_at_its_predicted_position_named_as_predicted() -> None:
    """uav2's last report is 3 s old: the monitor counts it where its motion off the plans
    puts it now (here 0.5 m from uav1), not where it was last heard (3 m away), and the
    pair is named with uav2 flagged as predicted."""
    plan = smooth_plan(short_line(2))
    vehicles = [fake_vehicle(0), fake_vehicle(1)]
    now = time.monotonic()
    for v, east in zip(vehicles, (0.0, 3.0), strict=True):
        v.phase = VehiclePhase.FLYING
        tel = v.linked.telemetry
        tel.position_ned, tel.velocity_ned = (0.0, east, -1.0), (0.0, 0.0, 0.0)
        tel.position_time = tel.message_time = now - (3.0 if v.id == "uav2" else 0.0)
    found = Findings(5.0, {"uav2": np.array([0.5, 0.0, 1.0])})
    monitor = FleetMonitor(vehicles, plan, FlightContext(FlightOptions(), lambda *_: None),
                           found)
    monitor.check_separation(monitor.positions(now))
    assert found.separations == [(pytest.approx(0.5), pytest.approx(0.7),
                                  "uav1 and uav2 (predicted: unheard)")]
    assert monitor.predicted_ids == {"uav2"}
    assert monitor.closest_text() == "uav1 and uav2 (predicted: unheard)"
