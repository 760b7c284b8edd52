"""The `fly` status table: one compact row per vehicle, never "None" or "nan"."""

from __future__ import annotations

import math

from rich.console import Console

from gcs.cli.fly_status import figure, header, status_table


def _vehicle(i: int, **changes) -> dict:
    v = {"id": f"uav{i}", "system_id": i, "phase": "flying", "fault": None, "mode": "OFFBOARD",
         "armed": True, "heartbeat_age": 0.4, "link_age": 0.02,
         "position": [1.0 * i, 2.0, 1.5], "velocity": [0.0, 0.0, 0.0], "tracking_error": 0.01}
    v.update(changes)
    return v


def _render(snap: dict, width: int = 100) -> str:
    console = Console(width=width, record=True, color_system=None)
    console.print(status_table(snap))
    return console.export_text()


def test_one_row_per_vehicle_and_no_none_or_nan() -> None:
    vehicles = [_vehicle(i) for i in range(1, 8)]
    vehicles.append(_vehicle(8, phase="pending", mode=None, armed=False, position=None,
                             tracking_error=math.nan, link_age=None, fault="link_lost"))
    snap = {"phase": "flying", "flight_time": 6.34, "horizon": 30.0,
            "min_separation_live": None, "vehicles": vehicles, "events": 3}
    text = _render(snap)
    lines = text.rstrip().splitlines()
    assert "None" not in text and "nan" not in text.lower()
    assert lines[0].startswith("flying · t 6.3 / 30 s · min separation -")
    rows = [line for line in lines if line.lstrip().startswith("uav")]
    assert [r.split()[0] for r in rows] == [f"uav{i}" for i in range(1, 9)]
    assert "link_lost" in rows[-1] and "pending" in rows[-1]
    assert max(len(line) for line in lines) <= 100  # compact: fits a terminal, 8 vehicles


def test_clock_stops_at_the_horizon_and_counts_the_time_past_it() -> None:
    snap = {"phase": "finishing", "flight_time": 37.34, "horizon": 30.0,
            "min_separation_live": 1.23456, "vehicles": []}
    assert header(snap) == "finishing · t 30.0 / 30 s +7.3 s · min separation 1.23 m"


def test_figure() -> None:
    assert figure(None) == "-" and figure(math.inf) == "-" and figure(math.nan) == "-"
    assert figure(0.123456, ".3f", " m") == "0.123 m"


def test_the_summary_names_the_goal_tolerance_applied_not_only_the_base() -> None:
    """PX4 SIH reports a GPS accuracy of 0.9 m, so each vehicle is judged within 1.8 m while
    the fleet's base tolerance is 0.5 m: the summary line says what was applied."""
    from gcs.cli.fly_cmd import tolerance_text

    sih = {"goal_tolerance": 0.5, "goal_tolerances": {"a": 1.8, "b": 1.8}}
    assert tolerance_text(sih) == "tolerance 1.800 m"
    mixed = {"goal_tolerance": 0.5, "goal_tolerances": {"a": 0.5, "b": 1.8}}
    assert tolerance_text(mixed) == "tolerances 0.500-1.800 m"
    assert tolerance_text({"goal_tolerance": 0.2, "goal_tolerances": {}}) == "tolerance 0.200 m"
    assert tolerance_text({"goal_tolerance": None}) == "tolerance n/a"
