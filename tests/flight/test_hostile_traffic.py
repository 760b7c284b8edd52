"""Hostile traffic on the px4-like mock: a signed fleet flying with its margin while
another local process sends every vehicle 40 unsigned LAND / force-DISARM commands per second
(`tests/flight/rejected_commands.py`, MAVSDK's way), and spoofs the vehicles' ACKs to the
GCS.

The vehicles reject the commands as PX4 does (`gcs.sim.receiver`: once the GCS has spoken
first, nobody moves their replies); the GCS drops the spoofs on their headers and tells them
live. The flight completes with its margin intact. No timing is asserted: what is judged is
what happened (completed, separation flown, rejections counted, events told)."""

from __future__ import annotations

import asyncio
import socket
from pathlib import Path
from typing import Any

import pytest

from gcs.errors import FlightAborted, VehicleTimeout
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.hub import LinkHub
from gcs.flight.procedure.vehicle import connect
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.safety.margin import scenario_for_fleet
from gcs.phases import EventKind
from gcs.sim import MockFleet, homes_under
from gcs.wire import mavlink, new_key_file, pack
from tests.flight.attacker import drain
from tests.flight.flying import Attacker
from tests.flight.support import FAST_MOCK, line_scenario, mock_ports, smooth_plan
from tests.support.waiting import until

pytestmark = [pytest.mark.timeout(150), pytest.mark.flight]

#: Rejected commands per second, per vehicle (what the floor asks the flight to withstand).
RATE = 40.0
POSITION_ERROR = 0.25


class CommandAttacker(Attacker):
    """`tests/flight/rejected_commands.py` in its own process, MAVSDK's way (its unsigned GCS
    HEARTBEAT at 1 Hz, which PX4 accepts with a key): commands to the vehicles' ports,
    spoofed ACKs to the GCS's."""

    module = "tests.flight.rejected_commands"

    def __init__(self, vehicles: list[tuple[int, int]], gcs_ports: list[int]) -> None:
        super().__init__([], [])
        self.args = ["--rate", str(RATE), "--duration", "90", "--style", "mavsdk", "--vehicles",
                     ",".join(f"127.0.0.1:{port}={system}" for port, system in vehicles),
                     "--gcs-ports", ",".join(map(str, gcs_ports))]


async def _fly(tmp_path: Path) -> tuple[dict[str, Any], MockFleet, dict[str, Any],
                                        list[tuple[str, int]]]:
    """The flight's record, the mock fleet, the attacker's report, and where each vehicle's
    replies went at the end (its offboard link's partner)."""
    # three vehicles side by side, planned for R 1 m + 2 x 0.25 m (the margin procedure),
    # 1.7 m apart: the px4 preset's wandering estimates alone bring side-by-side vehicles
    # 1.5 m apart to 1.12-1.21 m over a flight, which leaves a busy machine's stalls little
    plan = smooth_plan(scenario_for_fleet(line_scenario(3, spacing=1.7, steps=20),
                                          POSITION_ERROR))
    assert plan.scenario.min_separation == pytest.approx(1.5)
    key = new_key_file(tmp_path / "fleet.key")
    homes = homes_under(plan.scenario.starts)
    async with MockFleet(homes=homes, realism="px4", seed=5, signing_key=key.secret,
                         **mock_ports(len(homes)), **FAST_MOCK) as mock:
        fleet = FleetSpec.from_dict({**mock.fleet_dict(plan.scenario.ids),
                                     "signing_key": str(key.path),
                                     "position_error": POSITION_ERROR})
        executor = FlightExecutor(plan, fleet, FlightOptions(hold_at_goal=1.0, prestream=0.3,
                                                             climb_speed=2.0))
        task = executor.start()
        # the GCS speaks to the vehicles first (their replies are latched to it), as in
        # the SITL flights; then the attack starts, before the vehicles take off
        await until(lambda: task.done() or executor.phase not in ("created", "connecting"),
                    "the vehicles connected or the flight's end", timeout=60.0, poll=0.02)
        attacker = CommandAttacker(
            [(v.listen_address[1], v.system_id) for v in mock.vehicles],
            [v.gcs_port for v in mock.vehicles])
        await attacker.start()
        try:
            record = await task
        except FlightAborted:  # the record says why; the assertions below show it
            assert executor.record is not None
            record = executor.record
        report = await attacker.stop()
        return record, mock, report, [v.links[0].address for v in mock.vehicles]


def test_a_signed_flight_under_40_rejected_commands_a_second_keeps_its_margin(
        tmp_path: Path) -> None:
    record, mock, report, partners = asyncio.run(_fly(tmp_path))
    ids = [v["id"] for v in record["vehicles"]]
    summary = record["summary"]
    assert summary["completed"] is True, summary["why"]
    # the margin held: what the vehicles must keep (R = 1.5 - 2 x 0.25 m) was kept
    assert summary["min_separation_required"] == pytest.approx(1.0)
    assert summary["separation_held"] is True
    assert summary["min_separation_measured"] >= summary["min_separation_required"]
    assert not [e for e in record["events"] if e["kind"] == EventKind.SEPARATION_ALARM]
    # the attack ran at its rate and was rejected by every vehicle, counted by kind
    per_vehicle = report["commands"] / len(mock.vehicles)
    assert report["commands_per_s_per_vehicle"] > 0.25 * RATE and per_vehicle > 100, report
    for vehicle, partner in zip(mock.vehicles, partners, strict=True):
        counters = vehicle.intake.counters
        assert counters.rejected_unsigned >= 0.9 * per_vehicle, (vehicle.index, counters)
        assert counters.rejected_bad_signature == 0
        assert counters.unsigned_allowed >= 1  # its HEARTBEATs, accepted unsigned as by PX4
        # nothing it sent took the vehicle's replies: they went to the GCS all along
        assert partner == ("127.0.0.1", vehicle.gcs_port)
        assert not [e for _, e in vehicle.events if "failsafe" in e]
        assert [e for _, e in vehicle.events if e.startswith("disarmed")] == [
            "disarmed (auto disarm on land)"]  # the forced disarms did nothing
    assert report["received"] == 0  # no vehicle ever answered the attacker
    # the spoofed ACKs reached the GCS: dropped on their headers (another address than the
    # pinned vehicle), counted and told live
    told = {e["vehicle"] for e in record["events"] if e["kind"] == EventKind.DROPPED_PACKETS}
    assert told == set(ids) and len(ids) == len(mock.vehicles)
    for vid in ids:
        assert summary["security"][vid]["foreign_source"] >= 0.9 * per_vehicle


def test_a_rejected_packet_heard_first_takes_the_vehicles_replies_and_connect_says_so(
        tmp_path: Path) -> None:
    """As on PX4, the first datagram a vehicle hears fixes where its replies go, even an
    unsigned command its key makes it reject: the sender receives its telemetry, the GCS
    that connects afterwards hears nothing, and its error names that cause and the fix."""
    key = new_key_file(tmp_path / "fleet.key")

    async def run() -> tuple[str, int, int]:
        async with MockFleet(1, signing_key=key.secret, **mock_ports(1)) as mock:
            v = mock.vehicles[0]
            attacker = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            attacker.bind(("127.0.0.1", 0))
            attacker.setblocking(False)
            try:
                mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
                attacker.sendto(pack(mav.command_long_encode(
                    1, 1, mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0), mav),
                    v.listen_address)
                await asyncio.sleep(1.5)  # a HEARTBEAT (1 Hz) goes out meanwhile
                received, _types = drain(attacker)
                fleet = FleetSpec.from_dict({**mock.fleet_dict(["uav1"]),
                                             "signing_key": str(key.path)})
                async with LinkHub() as hub:
                    spec = fleet.vehicles[0]
                    link = await hub.add(spec.id, spec.connection, spec.system_id,
                                         signing_key=spec.signing_key, peer=spec.peer)
                    with pytest.raises(VehicleTimeout) as silent:
                        await connect(link, spec, 1.0)
                return str(silent.value), received, v.intake.counters.rejected_unsigned
            finally:
                attacker.close()

    error, received, rejected = asyncio.run(run())
    assert rejected == 1 and received > 10  # rejected, yet it got the telemetry
    assert "no HEARTBEAT" in error and "nothing at all arrived there" in error
    assert "first address it hears after boot" in error and "mavlink start -t" in error
