"""Vehicle health (gcs.flight.safety.health, the link's SYS_STATUS / BATTERY_STATUS /
GPS_RAW_INT and sequence-number accounting) and the pre-flight gate, on messages and on mock
vehicles."""

from __future__ import annotations

import asyncio

import pytest

from gcs.errors import PreflightFailed
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.endpoints import Endpoint
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import VehicleLink
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.safety.health import health_report, preflight_problems
from gcs.sim import MockFleet, homes_under
from gcs.wire import mavlink
from tests.flight.support import FAST_MOCK, QUICK, mock_ports, short_line, smooth_plan

pytestmark = pytest.mark.timeout(120)

FAST = QUICK.replace(preflight_wait=1.0)
GPS = mavlink.MAV_SYS_STATUS_SENSOR_GPS
GYRO = mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO
PREARM = mavlink.MAV_SYS_STATUS_PREARM_CHECK


def _link() -> tuple[VehicleLink, mavlink.MAVLink]:
    link = VehicleLink("uav1", Endpoint("udpin:127.0.0.1:9"), 1)
    return link, mavlink.MAVLink(None, srcSystem=1, srcComponent=1)


def _feed(link: VehicleLink, mav: mavlink.MAVLink, msg: object) -> None:
    msg.pack(mav)  # type: ignore[attr-defined]  # stamps mav.seq; counting up is send()'s job
    mav.seq = (mav.seq + 1) & 0xFF
    link.handle(msg, 0.0)


def test_health_from_messages() -> None:
    link, mav = _link()
    sensors = GPS | GYRO | PREARM
    _feed(link, mav, mav.sys_status_encode(sensors, sensors, sensors & ~GPS & ~PREARM, 0,
                                           15800, 0, 64, 0, 0, 0, 0, 0, 0))
    _feed(link, mav, mav.gps_raw_int_encode(0, 3, 0, 0, 0, 80, 120, 0, 0, 14, 0, 350, 700,
                                            0, 0, 0))
    mav.seq = (mav.seq + 3) & 0xFF  # three messages lost on the way
    _feed(link, mav, mav.statustext_encode(mavlink.MAV_SEVERITY_CRITICAL, b"Baro failure"))
    _feed(link, mav, mav.statustext_encode(mavlink.MAV_SEVERITY_INFO, b"Takeoff detected"))
    report = health_report(link.telemetry)
    assert report["battery"] == {"remaining_pct": 64, "voltage": pytest.approx(15.8)}
    assert report["gps"] == {"fix_type": 3, "satellites": 14, "h_acc": pytest.approx(0.35),
                             "v_acc": pytest.approx(0.7)}
    assert report["health"] == {"unhealthy": ["gps"], "prearm_ok": False,
                                "warnings": ["Baro failure"]}
    assert report["link_quality"] == {
        "received": 4, "lost": 3, "reordered": 0, "duplicates": 0, "restarts": 0,
        "loss_pct": pytest.approx(300 / 7, abs=0.01), "recent_loss_pct": None,
        "latency_ms": None, "jitter_ms": None}
    # the gate: battery fine (64%), but the GPS is unhealthy; no HEARTBEAT or position yet
    problems = preflight_problems(link.telemetry)
    assert problems == ["missing: no HEARTBEAT", "no position estimate (no LOCAL_POSITION_NED)",
                        "unhealthy: gps"]
    assert preflight_problems(link.telemetry, require_presence=False) == ["unhealthy: gps"]
    _feed(link, mav, mav.battery_status_encode(0, 0, 0, 0, [0] * 10, 0, 0, 0, 12))
    assert "battery 12% (below 30%)" in preflight_problems(link.telemetry)


def _heartbeat(mav: mavlink.MAVLink, armed: bool) -> object:
    base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
        mavlink.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0)
    return mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, base, 0,
                                mavlink.MAV_STATE_STANDBY)


def test_pre_arm_warnings_clear_when_the_vehicle_arms() -> None:
    """"Preflight Fail: ..." from before arming does not stay in the health report for the
    whole flight; a warning after arming stays, and a disarm-arm cycle clears it again."""
    link, mav = _link()
    _feed(link, mav, _heartbeat(mav, armed=False))
    _feed(link, mav, mav.statustext_encode(mavlink.MAV_SEVERITY_CRITICAL,
                                           b"Preflight Fail: heading estimate not stable"))
    _feed(link, mav, _heartbeat(mav, armed=False))
    assert health_report(link.telemetry)["health"]["warnings"] == \
        ["Preflight Fail: heading estimate not stable"]
    _feed(link, mav, _heartbeat(mav, armed=True))
    assert health_report(link.telemetry)["health"]["warnings"] == []
    _feed(link, mav, mav.statustext_encode(mavlink.MAV_SEVERITY_WARNING, b"Low battery"))
    _feed(link, mav, _heartbeat(mav, armed=True))
    assert health_report(link.telemetry)["health"]["warnings"] == ["Low battery"]
    # the text itself is kept in the vehicle's status texts
    assert "Preflight Fail: heading estimate not stable" in link.telemetry.statustexts


def _fly(configure, options: FlightOptions = FAST):
    plan = smooth_plan(short_line(2))

    async def main():
        homes = homes_under(plan.scenario.starts)
        async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(2),
                             **FAST_MOCK) as mock:
            configure(mock)
            fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
            executor = FlightExecutor(plan, fleet, options)
            try:
                outcome = await executor.run()
            except Exception as exc:
                outcome = exc
            return executor, outcome, mock

    return asyncio.run(main())


@pytest.mark.parametrize(("fault", "value", "reason"), [
    ("battery", 12.0, "battery 12% (below 30%)"),
    ("unhealthy", GPS, "unhealthy: gps"),
])
def test_the_gate_refuses_an_unfit_vehicle_before_anything_is_armed(
        fault: str, value: object, reason: str) -> None:
    def inject(mock: MockFleet) -> None:
        setattr(mock.vehicles[1].faults, fault, value)

    executor, outcome, mock = _fly(inject)
    assert isinstance(outcome, PreflightFailed), outcome
    assert outcome.vehicle == "uav2" and reason in str(outcome)
    assert not any(v.armed for v in mock.vehicles)
    assert not any(e == "armed" for v in mock.vehicles for _, e in v.events)
    assert executor.record is not None
    assert executor.record["error"]["type"] == "PreflightFailed"


@pytest.mark.flight
def test_an_override_flies_and_is_recorded_and_the_battery_drains() -> None:
    def inject(mock: MockFleet) -> None:
        mock.vehicles[1].faults.battery = 12.0

    _executor, record, mock = _fly(inject, FAST.replace(preflight="override"))
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True
    overrides = [e for e in record["events"] if e["kind"] == "preflight_override"]
    assert [e["vehicle"] for e in overrides] == ["uav2"]
    assert "battery 12%" in overrides[0]["detail"]
    # the simulated battery drains while armed (0.05 %/s by default)
    assert 95.0 < mock.vehicles[0].battery < 100.0


def test_link_loss_is_measured_from_sequence_numbers() -> None:
    async def main() -> float:
        async with MockFleet(homes=[[0, 0, 0]], settle_time=0.5, **mock_ports(1)) as mock:
            mock.vehicles[0].faults.loss = 0.3
            spec = FleetSpec.from_dict(mock.fleet_dict())
            async with LinkHub() as hub:
                v = spec.vehicles[0]
                link = await hub.add(v.id, v.connection, v.system_id)
                await asyncio.sleep(3.0)
                report = health_report(link.telemetry)["link_quality"]
                assert report["received"] > 50
                return report["loss_pct"]

    loss = asyncio.run(main())
    assert 20.0 < loss < 40.0
