"""A show that takes off from and lands on the ground is refused by `fleetplan fly` before
anything is armed, with the fix named (its own takeoff waves and landing legs are for a show
controller); a plan flown in the air is not."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from gcs.cli.main import main
from gcs.errors import PlanRejected
from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.run.ground import ground_refusal
from planner import Plan, Scenario, plan
from planner.methods.sequence import plan_sequence
from tests.api.support import QUICK_CROSSING
from tests.support.shows import FLEET_HOMES as HOMES
from tests.support.shows import fleet_dict
from tests.support.shows import ground_show as _show


@pytest.fixture(scope="module")
def ground_show() -> Plan:
    result = plan_sequence(_show(landing={}))
    assert result.ok, result.message
    return result.to_plan()


def test_a_show_on_the_ground_is_refused_with_the_fix(ground_show: Plan) -> None:
    why = ground_refusal(ground_show)
    assert why is not None
    assert "takes off from and lands on the ground" in why
    assert "fleetplan export PLAN.json --format skyc" in why


def test_a_plan_with_a_drone_parked_on_the_ground_is_refused_naming_it(
        ground_show: Plan) -> None:
    # the same trajectories without the show's ground block: still parked on the grid
    bare = dataclasses.replace(ground_show, sequence=None)
    why = ground_refusal(bare)
    assert why is not None
    assert f"vehicle {ground_show.scenario.ids[0]} stands on the ground" in why


def test_a_plan_in_the_air_is_flown() -> None:
    crossing = plan(Scenario.from_dict(QUICK_CROSSING))
    assert crossing.ok
    assert ground_refusal(crossing) is None


def test_fly_refuses_it_with_exit_2(ground_show: Plan, tmp_path: Path, capsys) -> None:
    path = tmp_path / "show.plan.json"
    path.write_text(json.dumps(ground_show.to_dict()))
    assert main(["fly", str(path), "--mock"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: refusing to fly the plan: it is a show that takes off")
    assert "--format skyc" in err and "Traceback" not in err


def test_the_executor_refuses_it_too(ground_show: Plan) -> None:
    """The Python API (FlightExecutor) refuses it before it holds any vehicle."""
    fleet = FleetSpec.from_dict(fleet_dict(list(ground_show.scenario.ids), HOMES))
    with pytest.raises(PlanRejected, match="takes off from and lands on the ground"):
        FlightExecutor(ground_show, fleet)
