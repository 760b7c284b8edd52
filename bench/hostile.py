"""A signed flight while a local process sends every vehicle 40 rejected commands/s.

Plans the 4-vehicle crossing for a fleet with position_error 0.25 m (R 1 m planned at 1.5 m,
the margin procedure of the issue), then flies it, signed, on 4 px4-like mock vehicles in a
process of their own (as PX4 SITL runs beside the GCS), once per case and repeat:

- ``quiet``: no attacker;
- ``raw``: `tests/flight/rejected_commands.py` sends each vehicle's port 40 unsigned
  COMMAND_LONG/s (NAV_LAND and force-DISARM alternately);
- ``mavsdk``: the same in MAVSDK's manner (its own unsigned GCS HEARTBEAT at 1 Hz, which PX4
  accepts, and retransmissions);
- ``both_ends``: ``raw``, and per command an unsigned COMMAND_ACK spoofed as the vehicle to
  the GCS's port (the GCS drops and reports it);
- ``hogs``: no attacker, two busy-looping processes (machine load alone);
- ``raw_hogs``: ``raw`` beside the two hogs;
- ``raw_first``: ``raw``, started before the vehicles boot, so that its rejected command is
  the first datagram each vehicle hears (PX4 latches its partner on it).

Except in ``raw_first``, the attacker starts once the GCS has connected (the vehicles' replies
are latched to it), as in the flights flown against PX4 SITL.

Per flight it prints the GCS's setpoint rate, tick jitter, missed ticks, tracking error,
separation flown and required, what the GCS dropped, what each vehicle accepted and rejected
(`gcs.sim.receiver`), what the attacker received back, and the load average; then the medians
per case; and what one rejected packet costs the GCS's signed link (refused on its header,
against decoded in full). Real time: about 25 s a flight.

    python bench/hostile.py                     # every case once
    python bench/hostile.py --repeats 3 --cases quiet,raw
    python bench/hostile.py --priority realtime     # the stream at real-time priority
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

# Run as `python bench/hostile.py`, this folder comes first on sys.path, where planner.py
# (the planner benchmark) would shadow the planner package: the project root goes first.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gcs.errors import GcsError
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.endpoints import UdpEndpoint
from gcs.flight.link.link import DECODED_IDS, VehicleLink
from gcs.flight.link.signing import LinkSigning
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.safety.margin import scenario_for_fleet
from gcs.sim import MockFleet, homes_under
from gcs.sim.ports import free_mock_fleet_ports
from gcs.wire import load_key, mavlink, new_key_file, parse_datagram
from planner import plan as make_plan
from tests.api.support import SHORT_CROSSING

ROOT = Path(__file__).resolve().parents[1]
CASES = ("quiet", "raw", "mavsdk", "both_ends", "hogs", "raw_hogs", "raw_first")
RATE = 40.0
"""Rejected commands per second per vehicle (the test's figure)."""
POSITION_ERROR = 0.25
HOG = "while True: pass"


async def _mock_child(spec: dict[str, Any]) -> None:
    """The mock fleet's process: start, say ready, run until stdin closes, print counters."""
    secret = load_key(spec["key"]).secret
    async with MockFleet(homes=spec["homes"], realism="px4", seed=spec["seed"],
                         signing_key=secret, gcs_base_port=spec["gcs_base_port"],
                         listen_base_port=spec["listen_base_port"]) as mock:
        print(json.dumps({"ready": True}), flush=True)
        await asyncio.get_running_loop().run_in_executor(None, sys.stdin.read)
        print(json.dumps({"vehicles": [
            {**vars(v.intake.counters), "partner": list(v.links[0].address),
             "errors": v.errors, "failsafes": [e for _, e in v.events if "failsafe" in e],
             "disarmed": [e for _, e in v.events if e.startswith("disarmed")]}
            for v in mock.vehicles]}), flush=True)


async def _start(args: list[str]) -> asyncio.subprocess.Process:
    """A child Python process that says ``{"ready": true}`` once started."""
    proc = await asyncio.create_subprocess_exec(
        sys.executable, *args, cwd=ROOT, stdin=asyncio.subprocess.PIPE,
        stdout=asyncio.subprocess.PIPE)
    assert proc.stdout is not None
    ready = json.loads(await proc.stdout.readline())
    assert ready == {"ready": True}, ready
    return proc


async def _finish(proc: asyncio.subprocess.Process) -> dict[str, Any]:
    """Close the child's stdin (it stops) and read its last JSON line."""
    assert proc.stdin is not None
    proc.stdin.close()
    out, _ = await asyncio.wait_for(proc.communicate(), 30)
    return json.loads(out.decode().strip().splitlines()[-1])


async def _attacker(case: str, listen: list[int], gcs: list[int]
                    ) -> asyncio.subprocess.Process:
    style = "mavsdk" if case == "mavsdk" else "raw"
    args = ["-m", "tests.flight.rejected_commands", "--rate", str(RATE), "--duration", "120",
            "--style", style, "--vehicles",
            ",".join(f"127.0.0.1:{p}={i + 1}" for i, p in enumerate(listen))]
    if case == "both_ends":
        args += ["--gcs-ports", ",".join(map(str, gcs))]
    return await _start(args)


async def fly_case(case: str, plan: Any, key: Path, seed: int, priority: str = "normal"
                   ) -> dict[str, Any]:
    """One signed flight with `case`'s attacker and load; its figures."""
    homes = homes_under(plan.scenario.starts)
    ports = free_mock_fleet_ports(len(homes))
    listen = [ports["listen_base_port"] + i for i in range(len(homes))]
    gcs = [ports["gcs_base_port"] + i for i in range(len(homes))]
    spec = {"homes": homes, "seed": seed, "key": str(key), **ports}
    load_before = os.getloadavg()
    attacker = None
    if case == "raw_first":  # speaks to the vehicles before the GCS does
        attacker = await _attacker(case, listen, gcs)
    mock = await _start([str(Path(__file__).resolve()), "--mock-child", json.dumps(spec)])
    hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(
        2 if case.endswith("hogs") else 0)]
    try:
        fleet = FleetSpec.from_dict({
            "signing_key": str(key), "position_error": POSITION_ERROR,
            "vehicles": [{"id": vid, "connection": f"udpin:127.0.0.1:{gcs[i]}",
                          "system_id": i + 1, "home": homes[i],
                          "peer": f"127.0.0.1:{listen[i]}"}
                         for i, vid in enumerate(plan.scenario.ids)]})
        executor = FlightExecutor(plan, fleet, FlightOptions(hold_at_goal=1.0,
                                                             stream_priority=priority))
        task = executor.start()
        if case not in ("quiet", "hogs", "raw_first"):
            # the GCS spoke first (the vehicles' replies are latched to it), as in the issue
            while executor.phase in ("created", "connecting") and not task.done():
                await asyncio.sleep(0.02)
            attacker = await _attacker(case, listen, gcs)
        try:
            record = await task
        except GcsError:  # aborted or failed: its record says why
            assert executor.record is not None
            record = executor.record
    finally:
        report = await _finish(attacker) if attacker is not None else None
        for hog in hogs:
            hog.kill()
            hog.wait()
        vehicles = (await _finish(mock))["vehicles"]
    s = record["summary"]
    return {"case": case, "seed": seed, "completed": s["completed"], "why": s["why"],
            "setpoint_rate_hz": s["setpoint_rate_hz"], "jitter_p50_ms": s["jitter_p50_ms"],
            "jitter_p99_ms": s["jitter_p99_ms"], "missed_ticks": s["missed_ticks"],
            "tracking_error_max_m": s["tracking_error_max"],
            "min_separation_measured_m": s["min_separation_measured"],
            "min_separation_required_m": s["min_separation_required"],
            "separation_held": s["separation_held"],
            "goal_error_max_m": s["goal_error_max"],
            "dropped_by_gcs": {vid: sum(v for k, v in c.items() if k not in (
                "invalid_estimates", "link_garbage_datagrams")) for vid, c in
                s["security"].items()},
            "dropped_packets_events": sum(e["kind"] == "dropped_packets"
                                          for e in record["events"]),
            "vehicles": vehicles, "attacker": report,
            "load_average_before": [round(x, 2) for x in load_before],
            "load_average_after": [round(x, 2) for x in os.getloadavg()]}


def rejection_cost(n: int = 20_000) -> dict[str, float]:
    """What one unsigned COMMAND_LONG from the vehicle's own address costs the GCS's signed
    link (us): refused on its header (`Receiver.refuses`, what the GCS does) against decoded
    in full and then dropped (what it did before)."""
    with tempfile.TemporaryDirectory() as tmp:
        signing = LinkSigning(new_key_file(Path(tmp) / "k.key"))
        endpoint = UdpEndpoint("udpin:127.0.0.1:9", DECODED_IDS)  # never opened
        peer = ("127.0.0.1", 14580)
        link = VehicleLink("v", endpoint, 1, 1, signing=signing, peer=peer)
        attacker = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        buf = attacker.command_long_encode(1, 1, mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0,
                                           0, 0).pack(attacker)
        start = time.perf_counter()
        for _ in range(n):
            endpoint.received(buf, peer)
        refused = (time.perf_counter() - start) / n * 1e6
        start = time.perf_counter()
        for _ in range(n):
            now = time.monotonic()
            for msg in parse_datagram(buf).messages:
                endpoint._dispatch(msg, peer, now)
        decoded = (time.perf_counter() - start) / n * 1e6
        assert link.telemetry.security.unsigned == 2 * n
    return {"refused_on_header_us": round(refused, 2), "decoded_then_dropped_us":
            round(decoded, 2)}


def _median(flights: list[dict[str, Any]], key: str) -> float | None:
    values = [f[key] for f in flights if f[key] is not None]
    return round(statistics.median(values), 3) if values else None


def summarize(flights: list[dict[str, Any]]) -> dict[str, Any]:
    """Medians (and extremes where they matter) of a case's flights."""
    return {"flights": len(flights), "completed": sum(f["completed"] for f in flights),
            **{key: _median(flights, key) for key in (
                "setpoint_rate_hz", "jitter_p50_ms", "jitter_p99_ms", "missed_ticks",
                "tracking_error_max_m", "min_separation_measured_m", "goal_error_max_m")},
            "min_separation_measured_min_m": min(
                (f["min_separation_measured_m"] for f in flights
                 if f["min_separation_measured_m"] is not None), default=None),
            "rejected_by_vehicles": sum(v["rejected_unsigned"] + v["rejected_bad_signature"]
                                        for f in flights for v in f["vehicles"]),
            "unsigned_allowed_by_vehicles": sum(v["unsigned_allowed"] for f in flights
                                                for v in f["vehicles"]),
            "attacker_received": sum((f["attacker"] or {}).get("received", 0)
                                     for f in flights)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=1, help="flights per case (default 1)")
    parser.add_argument("--cases", default=",".join(CASES), help="comma-separated, of "
                        + ", ".join(CASES))
    parser.add_argument("--priority", choices=("normal", "realtime"), default="normal",
                        help="the stream's priority (default normal, as the station of the "
                             "SITL flights; realtime needs CAP_SYS_NICE)")
    parser.add_argument("--mock-child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.mock_child:
        asyncio.run(_mock_child(json.loads(args.mock_child)))
        return
    cases = args.cases.split(",")
    unknown = sorted(set(cases) - set(CASES))
    if unknown:
        parser.error(f"--cases: unknown {', '.join(unknown)} (known: {', '.join(CASES)})")
    plan = make_plan(scenario_for_fleet(SHORT_CROSSING, POSITION_ERROR))
    out: dict[str, Any] = {"machine": {"python": platform.python_version(),
                                       "cpus": os.cpu_count(),
                                       "load_average": list(os.getloadavg())},
                           "rate_per_vehicle": RATE, "position_error": POSITION_ERROR,
                           "stream_priority": args.priority,
                           "min_separation_planned": plan.scenario.min_separation,
                           "gcs_cost_per_rejected_packet": rejection_cost(), "cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        key = new_key_file(Path(tmp) / "fleet.key").path
        flights: dict[str, list[dict[str, Any]]] = {case: [] for case in cases}
        for seed in range(args.repeats):  # interleaved: the machine's load drifts
            for case in cases:
                flights[case].append(asyncio.run(fly_case(case, plan, key, seed,
                                                          args.priority)))
    for case in cases:
        out["cases"][case] = {"summary": summarize(flights[case]), "flights": flights[case]}
    out["machine"]["load_average_after"] = list(os.getloadavg())
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
