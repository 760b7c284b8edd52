"""The flight summary's separation verdict: judged with the planner's tolerance, worded with
figures that differ when they must, and never silent when the separation is unknown."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.run.record import FlightRecorder
from gcs.flight.run.summary import summarise
from planner.verification.verify import SEPARATION_TOLERANCE
from tests.flight.support import line_scenario, smooth_plan


def _summary(gap: float, *, reports: int = 80, margin: float = 0.0,
             nan_report: bool = False, phase: str = "landed") -> dict[str, Any]:
    """The summary of a 2-vehicle flight whose vehicles hover `gap` m apart along x, every
    vehicle landed within a few cm of its goal (faked executor view)."""
    plan = smooth_plan(line_scenario(2))
    if margin:
        plan = dataclasses.replace(plan, scenario=dataclasses.replace(
            plan.scenario, separation_margin=margin))
    recorder = FlightRecorder(["uav1", "uav2"], [1, 2])
    horizon = plan.scenario.horizon
    for n, vid in enumerate(["uav1", "uav2"]):
        rec = recorder.vehicles[vid]
        count = reports if n == 1 else 80
        rec.tel_t = list(np.linspace(0.0, horizon + 2.0, count))
        rec.tel_pos = [[1.0 + n * gap, 1.0, 1.5]] * count
        if nan_report and n == 1:
            rec.tel_pos[3] = [math.nan, 1.0, 1.5]
    vehicles = [SimpleNamespace(id=vid, index=n, fault=None, fault_time=None,
                                goal_error=0.05, goal_tolerance=math.nan,
                                phase="landed" if n == 0 else phase,
                                link=None, dropped=None, drop_reason=None)
                for n, vid in enumerate(["uav1", "uav2"])]
    return summarise(recorder, plan, FlightOptions(), vehicles, flight_start=0.0,
                     now=horizon + 3.0, missed_ticks=0, lateness=None, error=None)


def test_a_gap_within_the_planner_tolerance_is_held():
    """0.99993 m for R = 1 m: the planner verifies such a plan (tolerance 1e-4 m), so the
    flight holds it too; it is not reported as '1.00 m apart, closer than the 1.00 m'."""
    summary = _summary(1.0 - 0.7 * SEPARATION_TOLERANCE)
    assert summary["min_separation_measured"] == pytest.approx(0.99993)
    assert summary["separation_held"] is True
    assert summary["completed"] is True
    assert not any("closer than" in line for line in summary["why"])


def test_a_breach_is_worded_with_figures_that_differ():
    summary = _summary(1.0 - 3 * SEPARATION_TOLERANCE)
    assert summary["separation_held"] is False
    line = next(line for line in summary["why"] if "closer than" in line)
    assert "0.9997 m apart" in line and "1.0000 m" in line


@pytest.mark.parametrize("broken", [{"reports": 1}, {"nan_report": True}])
def test_an_unknown_separation_is_said(broken):
    """Too few reports, or a NaN position: the measured minimum is unknown. The summary
    says so; it never reads completed without saying so."""
    summary = _summary(0.4, **broken)
    assert summary["min_separation_measured"] is None
    assert summary["separation_held"] is None
    assert any("separation" in line and "unknown" in line for line in summary["why"])
    if summary["completed"]:
        assert "separation unknown" in summary["why"][0]


def test_an_unknown_separation_breaks_a_promised_margin():
    """With a stated margin the separation is a promise: unknown is not kept."""
    summary = _summary(3.0, reports=1, margin=0.2)
    assert summary["separation_held"] is None
    assert summary["completed"] is False


def test_landed_then_out_of_reach_is_told_apart_from_hovering():
    summary = _summary(2.0, phase="landed_link_lost")
    assert summary["completed"] is False
    assert "uav2: landed and disarmed when last heard, then out of reach (link lost)" \
        in summary["why"]
    hovering = _summary(2.0, phase="hovering")
    assert "uav2: not confirmed landed and disarmed (hovering)" in hovering["why"]


@pytest.mark.parametrize("abort_at", [None, 4.0])
def test_an_abort_ends_the_tracking_and_the_time_after_it_is_told_apart(abort_at):
    """Two vehicles on their plan until t = 4 s, then straight down (an abort's landing): the
    tracking error is the one before the abort, the landing is the time after it; without
    the abort the same descent is a tracking error."""
    plan = smooth_plan(line_scenario(2))
    recorder = FlightRecorder(["uav1", "uav2"], [1, 2])
    t = np.linspace(0.0, 8.0, 161)
    for n, vid in enumerate(["uav1", "uav2"]):
        rec = recorder.vehicles[vid]
        planned = plan.vehicles[n].sample(plan.scenario.dt, np.minimum(t, 4.0)).position
        planned[t > 4.0, 2] -= (t[t > 4.0] - 4.0) * 0.5  # down at 0.5 m/s
        rec.tel_t, rec.tel_pos = list(t), planned.tolist()
    if abort_at is not None:
        recorder.event(abort_at, None, "abort", "operator abort: land all")
    vehicles = [SimpleNamespace(id=vid, index=n, fault=None, fault_time=None,
                                goal_error=2.0, goal_tolerance=math.nan, phase="landed",
                                link=None, dropped=None, drop_reason=None)
                for n, vid in enumerate(["uav1", "uav2"])]
    summary = summarise(recorder, plan, FlightOptions(), vehicles, flight_start=0.0,
                        now=8.0, missed_ticks=0, lateness=None, error=None)
    if abort_at is None:
        assert summary["tracking_error_max"] > 1.5  # the descent, 2 m below the plan
        assert summary["aborted_at"] is None and summary["after_abort_s"] is None
    else:
        assert summary["tracking_error_max"] == pytest.approx(0.0, abs=1e-9)
        assert summary["aborted_at"] == 4.0 and summary["after_abort_s"] == 4.0
