"""The benchmark scripts run as documented (`python bench/NAME.py`, from any directory) and
print the JSON the README's figures come from. Their timings are not asserted here."""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

from tests.flight.support import QUICK_MOCK_ENV

BENCH = Path(__file__).resolve().parents[2] / "bench"


def _run(script: str, *args: str, env: dict[str, str] | None = None) -> dict:
    done = subprocess.run([sys.executable, str(BENCH / script), *args], capture_output=True,
                          text=True, timeout=300, cwd="/", env={**os.environ, **(env or {})})
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_planner_benchmark_reports_figures_and_machine():
    report = _run("planner.py", "--only", "paper-circle2", "--repeats", "1",
                  "--dmpc-sizes", "4", "--dmpc-trials", "1", "--no-solver-comparison",
                  "--row-modes")
    row = report["scenarios"][0]
    assert row["scenario"] == "paper-circle2" and row["status"] == "converged"
    assert row["min_separation_continuous"] >= row["R"] - 1e-4
    assert row["vehicles"] == 2 and row["verified"] is True
    assert row["qp_solves"] >= row["scp_iterations"] >= 1
    # One repeat: the reported time is that run's, the first QP is part of it, and the
    # speed-up is computed from the figures it prints.
    assert row["total_s_runs"] == [pytest.approx(row["total_s"], abs=1e-4)]
    assert row["first_qp_s"] <= row["total_s"]
    assert row["speedup_vs_paper"] == pytest.approx(row["paper_total_s"] / row["total_s"])
    assert row["peak_rss_mb"] is None or row["peak_rss_mb"] > 0  # None off Linux
    assert report["dmpc2019"]["4"]["trials"] == 1 and report["dmpc2019"]["4"]["verified"] == 1
    # The machine it ran on, as this process sees it.
    assert report["machine"]["cpus"] == os.cpu_count()
    assert report["machine"]["packages"]["numpy"] == metadata.version("numpy")


def test_planner_benchmark_runs_an_obstacle_family_against_its_floor():
    report = _run("planner.py", "--only", "--dmpc-sizes", "--no-solver-comparison",
                  "--row-modes", "--repeats", "1", "--no-memory", "--obstacles",
                  "pillar-circle8", "--seeds", "1")
    [row] = report["families"]
    assert (row["family"], row["seed"], row["vehicles"], row["obstacles"]) == (
        "pillar-circle8", 1, 8, 1)
    assert row["status"] == "converged" and row["verified"] is True
    assert row["obstacle_distance_min"] >= row["clearance"] - 1e-4
    assert row["closest_obstacle"]["id"] == "pillar"
    assert row["floor_s"] == 0.5 and row["within_floor"] == (row["total_s"] <= 0.5)
    assert row["method"] == "auto" and row["planned_by"] in ("whole", "prioritized")
    assert {a["method"]: a["outcome"] for a in row["attempts"]}[row["planned_by"]] == "won"


def test_planner_benchmark_plans_a_family_in_prioritized_batches_when_asked():
    report = _run("planner.py", "--only", "--dmpc-sizes", "--no-solver-comparison",
                  "--row-modes", "--repeats", "1", "--no-memory", "--obstacles",
                  "window8", "--seeds", "0", "--decompose", "prioritized")
    [row] = report["families"]
    assert row["method"] == "prioritized" and row["planned_by"] == "prioritized"
    assert row["message"].startswith("planned in 4 prioritized batches")
    assert row["status"] == "converged" and row["verified"] is True
    assert row["obstacle_distance_min"] >= row["clearance"] - 1e-4
    assert report["families_summary"][0]["method"] == "prioritized"


def test_floors_benchmark_reports_verified_medians_against_each_floor():
    report = _run("floors.py", "--only", "paper-random2", "pillar-circle8", "--repeats", "2")
    paper, pillar = report["cases"]
    assert (paper["case"], paper["vehicles"], paper["floor_of"]) == ("paper-random2", 2,
                                                                     "planner")
    assert (pillar["case"], pillar["floor_s"], pillar["floor_of"]) == ("pillar-circle8", 0.5,
                                                                       "wall")
    for row in (paper, pillar):
        assert len(row["planner_s"]) == len(row["cpu_s"]) == 2
        assert row["median_planner_s"] == pytest.approx(statistics.median(row["planner_s"]),
                                                        abs=1e-4)
        measured = row["median_planner_s"] if row["floor_of"] == "planner" \
            else row["median_wall_s"]
        assert row["meets_floor"] == (measured <= row["floor_s"])
        assert row["method"] in ("whole", "prioritized", "separated_first")
        assert row["iterations"] >= 1
    assert report["cpus"] == os.cpu_count() and len(report["load_average_at_start"]) == 3


def test_stream_benchmark_reports_rate_and_jitter():
    report = _run("stream.py", "--vehicles", "3", "--rate", "20", "--duration", "2")
    for kind in ("pack_setpoint", "receive_position"):
        assert report["per_message_us"][kind]["signed"] > 0
        assert report["per_message_us"][kind]["unsigned"] > 0
    assert report["scenario"]["stream_priority"] == "realtime"  # the flights' default
    for mode in ("unsigned", "signed"):  # both by default
        median, run = report[mode]["median"], report[mode]["runs"][0]
        # Setpoints went out, never faster than the rate: 41 ticks fit in 2 s.
        assert run["setpoints_sent"] > 0
        assert 0 < median["achieved_rate_hz"] <= 20.0 * 41 / 40 + 0.5
        assert report[mode]["floor"]["jitter_p99_ms"] == 2.0
        # the signed run really was signed end to end: no telemetry dropped as unsigned
        assert report[mode]["runs"][0]["telemetry_dropped_by_security"] == 0
        assert report[mode]["runs"][0]["telemetry_messages_received_first_endpoint"] > 0


def test_stream_benchmark_at_px4_rates_with_and_without_rate_requests():
    report = _run("stream.py", "--vehicles", "2", "--rate", "20", "--duration", "2",
                  "--telemetry", "px4", "--message-rates", "leave,request", "--modes",
                  "unsigned")
    assert report["scenario"]["telemetry"] == "px4"
    leave, request = (report[f"unsigned/{m}"]["runs"][0] for m in ("leave", "request"))
    assert leave["telemetry_skipped_per_s"] > 0  # unread ids dropped before decoding
    assert request["rate_requests_refused"] == []
    # asked for what it reads, the GCS receives a fraction of PX4's ~410/s per vehicle
    assert request["telemetry_per_s"] < 0.3 * leave["telemetry_per_s"]
    for run in (leave, request):
        assert run["telemetry_latency_p50_ms"] > 0
        assert run["link_loss_percent"] < 1.0
        assert set(run["stalls"]) == {"busy", "descheduled"}
    assert report["per_message_us"]["skip_attitude"]["unsigned"] > 0


@pytest.mark.flight
def test_service_benchmark_reports_latency_and_flight_timing():
    # the service it starts reads the mock settings from the environment: quick mocks
    report = _run("service.py", "--scenario", "paper-circle8", "--flight", "quick",
                  "--hold-at-goal", "0.5", env=QUICK_MOCK_ENV)
    run = report["runs"][0]
    assert run["plan_status"] == "planned" and run["flight"]["status"] == "completed"
    latency = run["latency"]
    assert latency["p50_ms"] > 0
    assert latency["requests"] == sum(p["requests"] for p in run["by_path"].values())
    # One run: the medians and the worst case are that run's own figures.
    assert report["scenario"]["planned_meanwhile"] == "paper-circle8"
    assert report["scenario"]["vehicles"] == 8 and report["scenario"]["repeat"] == 1
    assert report["scenario"]["crossing"] == "quick"
    assert report["median"]["setpoint_rate_hz"] == run["flight"]["setpoint_rate_hz"]
    assert report["median"]["latency_max_ms"] == latency["max_ms"]
    assert report["missed_ticks_max"] == (run["flight"]["missed_ticks"] or 0)


def test_landing_benchmark_reports_verified_landings():
    """bench/landing.py on the paper circle's states and a small random crowd's: every
    landing verified, R kept, each figure counted in the summary."""
    report = _run("landing.py", "--sizes", "8", "12", "--seeds", "0", "--times", "6",
                  "--crowd-states", "12")
    assert report["benchmark"] == "landing" and report["cpus"] == os.cpu_count()
    states = [c["state"] for c in report["cases"]]
    assert states == ["paper-circle8 at t=6 s", "random crowd"]
    for case in report["cases"]:
        assert case["ok"] is True
        assert case["min_separation_continuous"] >= case["separation_kept"] - 1e-4
    assert report["summary"]["8"]["verified"] == 1 and report["summary"]["12"]["cases"] == 1


def test_replan_benchmark_reports_verified_replans_from_mid_crossing():
    """bench/replan.py on a 16-vehicle circle swap at its centre (everyone crossing, the
    drop in the others' way): both variants verified, R (or a hair less) kept, also from the
    dropped vehicle's landing, and the summary counts them."""
    report = _run("replan.py", "--families", "circle", "--sizes", "16", "--seeds", "0",
                  "--at", "0.5")
    assert report["benchmark"] == "replan" and report["machine"]["cpus"] == os.cpu_count()
    runs = report["runs"]
    assert [r["variant"] for r in runs] == ["goals+drop", "goals"]
    for run in runs:
        assert run["ok"] is True and run["verified"] is True, run
        assert run["goals_changed"] == 4
        assert run["min_separation_continuous"] >= run["separation_kept"] - 1e-4
    assert runs[0]["dropped"] and runs[0]["fixed_distance_min"] >= runs[0]["separation_kept"] - 1e-4
    assert runs[1]["dropped"] is None and runs[1]["fixed_distance_min"] is None
    assert report["summary"]["circle/16/goals+drop"]["verified"] == 1
    assert report["by_size"]["16"]["floor_s"] == 0.3


def test_export_benchmark_reports_time_size_and_pieces():
    report = _run("export.py", "--vehicles", "4", "--repeats", "2")
    (row,) = report["sizes"]
    assert row["vehicles"] == 4 and row["plan_ok"] is True
    assert len(row["export_s_runs"]) == 2 and row["export_s"] > 0
    # A ZIP of deflated JSON: smaller than the JSON it holds; one keyframe per step at most.
    assert 0 < row["skyc_bytes"] < row["show_json_bytes"]
    assert 0 < row["keyframes"] <= row["keyframes_one_per_step"] == 4 * (row["steps"] + 1)
    assert 0 < row["largest_piece_bytes"] <= row["skyc_bytes"]
    assert report["machine"]["cpus"] == os.cpu_count()


def test_geofence_benchmark_uploads_every_vehicles_fence():
    """bench/geofence.py: every vehicle's fence (workspace + pillars) uploaded, read back the
    same (send_fence raises otherwise) and timed."""
    report = _run("geofence.py", "--vehicles", "2", "--pillars", "3", "--repeat", "1")
    assert report["vehicles"] == 2 and report["items_per_vehicle"] == 4 + 3
    assert report["fleet_upload_s_max"] >= report["fleet_upload_s_median"] > 0


@pytest.mark.flight
def test_station_loss_benchmark_lands_a_fleet_whose_columns_are_apart():
    """bench/station_loss.py: paper-circle4 planned with its columns apart, every link
    blackholed at 4 s (a station lost): each vehicle lands on its own failsafe, and the
    closest true approach is reported against R."""
    report = _run("station_loss.py", "--plans", "paper-circle4", "--columns", "--at", "4")
    assert report["case"] == "station lost" and report["failsafe"] == "land by layer"
    row = report["plans"]["paper-circle4"]
    assert row["vehicles"] == 4 and row["stacked_columns"] is None
    [run] = row["runs"]
    assert run["at"] == 4.0 and run["all_down"] is True and run["samples"] > 500
    assert row["closest_m"] == run["closest_m"] >= row["R"] - 0.05
    assert row["kept_r_minus_5cm"] is True


def test_flight_list_benchmark_lists_summaries_smaller_than_the_events():
    report = _run("flight_list.py", "--flights", "3", "--events", "50", "--repeat", "1")
    assert (report["flights"], report["events_per_flight"]) == (3, 50)
    full, listed = report["mission_flights_with_events"], report["flight_summaries"]
    assert "mission_id=" in listed["url"] and listed["bytes"] < full["bytes"]
    assert report["cpu_ratio"] == pytest.approx(
        full["cpu_s_median"] / max(listed["cpu_s_median"], 1e-9), rel=0.01, abs=0.1)
