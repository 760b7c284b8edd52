"""Setpoint streaming benchmark: N mock vehicles in another process, one GCS process streaming.

Starts `fleetplan mock` (python -m gcs.cli.main mock) with N vehicles on free ports, connects
one `gcs.flight.link.LinkHub`, and streams every vehicle a moving setpoint track through the shared
clock (`gcs.flight.stream.Streamer`) at RATE Hz for DURATION s. Prints one JSON document: scenario,
achieved rate, send-instant jitter p50/p99/max (lateness of each send against its tick's
scheduled instant), missed ticks, CPU of the GCS process and of the mock process, machine
info. With --repeat R it runs R times per mode and also reports the medians. Floor: p99 jitter
< 5 ms with no missed tick.

Modes (--modes): ``unsigned``, and ``signed``: MAVLink 2 signing end to end (a fresh key is
provisioned on the mock vehicles with SETUP_SIGNING over a first, unsigned connection, then the
GCS reconnects signed; every setpoint is signed, every telemetry packet verified).

It also reports the CPU cost per message in this process (`per_message_us`: encoding one
setpoint, receiving one LOCAL_POSITION_NED datagram, unsigned and signed; the minimum of 5
repeats, so it holds on a busy machine where the jitter figures do not).

    python bench/stream.py                      # 100 vehicles, 50 Hz, 30 s, both modes
    python bench/stream.py --duration 5 --repeat 3 --modes signed
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

# Run as `python bench/stream.py`, this folder comes first on sys.path, where planner.py
# (the planner benchmark) would shadow the planner package: the project root goes first.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from gcs.flight.link import LinkHub, UdpEndpoint, VehicleLink
from gcs.flight.setpoints import Setpoint, SetpointTrack
from gcs.flight.signing import LinkSigning
from gcs.flight.stream import Streamer, jitter_stats
from gcs.sim.ports import free_udp_base
from gcs.wire import SigningKey, mavlink, new_key_file, signing_timestamp


def proc_cpu_seconds(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


async def provision(base: int, vehicles: int, key: SigningKey) -> None:
    """SETUP_SIGNING to every mock vehicle over an unsigned (trusted, loopback) connection."""
    async with LinkHub() as hub:
        links = [await hub.add(f"v{i}", f"udpin:127.0.0.1:{base + i}", i + 1)
                 for i in range(vehicles)]
        for link in links:
            if not await link.wait_for(lambda t: t.heartbeat_time is not None, 10.0):
                raise RuntimeError(f"no heartbeat from {link.vehicle_id}")
            link.send_setup_signing(key, signing_timestamp(time.time()))
        await asyncio.sleep(0.5)


async def one_run(vehicles: int, rate: float, duration: float,
                  key: SigningKey | None = None) -> dict:
    base = free_udp_base(range(2 * vehicles))
    mock = subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "mock", "--vehicles", str(vehicles),
         "--base-port", str(base), "--listen-base-port", str(base + vehicles),
         "--settle", "0"], stdout=subprocess.PIPE, text=True)
    try:
        assert mock.stdout is not None
        mock.stdout.readline()  # "mock: N PX4-like vehicles ..." once it listens
        if key is not None:
            await provision(base, vehicles, key)
        async with LinkHub() as hub:
            links = [await hub.add(f"v{i}", f"udpin:127.0.0.1:{base + i}", i + 1,
                                   signing_key=key)
                     for i in range(vehicles)]
            for link in links:
                if not await link.wait_for(lambda t: t.heartbeat_time is not None, 10.0):
                    raise RuntimeError(f"no heartbeat from {link.vehicle_id}")
            # a circle of radius 1 m at 2 m altitude, one per vehicle
            ticks = int(duration * rate) + 1
            phase = np.arange(ticks) / rate
            pos = np.stack([np.cos(phase), np.sin(phase), np.full(ticks, -2.0)], axis=1)
            vel = np.stack([-np.sin(phase), np.cos(phase), np.zeros(ticks)], axis=1)
            acc = np.stack([-np.cos(phase), -np.sin(phase), np.zeros(ticks)], axis=1)
            track = SetpointTrack(pos, vel, acc, 0.0, rate)
            streamer = Streamer(rate)
            start = streamer.next_tick() + 1
            for link in links:
                streamer.assign(link.vehicle_id, link, track, start)
            streamer.measuring = True
            cpu0 = time.process_time()
            mock_cpu0 = proc_cpu_seconds(mock.pid)
            wall0 = time.monotonic()
            streamer.start()
            await asyncio.sleep(duration)
            await streamer.stop()
            wall = time.monotonic() - wall0
            cpu = time.process_time() - cpu0
            mock_cpu = proc_cpu_seconds(mock.pid) - mock_cpu0
            sent = sum(link.setpoints_sent for link in links)
            received = sum(link.endpoint.messages_received for link in links[:1])
            dropped = sum(link.telemetry.security.total for link in links)
    finally:
        mock.terminate()
        mock.wait(timeout=10)
    stats = jitter_stats(streamer.lateness)
    return {
        "achieved_rate_hz": sent / vehicles / wall,
        **{k: round(v, 3) for k, v in stats.items()},
        "missed_ticks": streamer.missed_ticks,
        "setpoints_sent": sent,
        "gcs_cpu_percent": round(100.0 * cpu / wall, 1),
        "mock_cpu_percent": round(100.0 * mock_cpu / wall, 1),
        "telemetry_messages_received_first_endpoint": received,
        "telemetry_dropped_by_security": dropped,
    }


def per_message_costs(key: SigningKey, count: int = 2000) -> dict:
    """Microseconds of CPU per setpoint encoded and per telemetry datagram received (parse,
    pinning, signature check, telemetry update), unsigned and signed; min of 5 repeats."""
    out: dict[str, dict[str, float]] = {"pack_setpoint": {}, "receive_position": {}}
    setpoint = Setpoint((1.0, 2.0, -3.0), (0.1, 0.2, 0.3), (0.0, 0.0, 0.0), 0.0)
    for mode in ("unsigned", "signed"):
        signing = LinkSigning(key) if mode == "signed" else None
        endpoint = UdpEndpoint("udpin:127.0.0.1:9")  # never opened: no socket needed
        link = VehicleLink("v", endpoint, 1, 1, signing=signing)
        pack = min(timeit.repeat(lambda link=link: link.pack_setpoint(setpoint, 0),
                                 number=count, repeat=5)) / count
        vehicle = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        if signing is not None:
            vehicle.signing.secret_key = key.secret
            vehicle.signing.sign_outgoing = True
            vehicle.signing.timestamp = signing_timestamp(time.time())
        times = []
        for _ in range(5):
            datagrams = iter([vehicle.local_position_ned_encode(0, 1, 2, -3, 0, 0, 0).pack(
                vehicle) for _ in range(count)])
            times.append(timeit.timeit(
                lambda e=endpoint, d=datagrams: e._received(next(d), ("127.0.0.1", 1)),
                number=count) / count)
        if link.telemetry.security.total:
            raise RuntimeError(f"{mode}: telemetry dropped {link.telemetry.security}")
        out["pack_setpoint"][mode] = round(pack * 1e6, 1)
        out["receive_position"][mode] = round(min(times) * 1e6, 1)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, default=100)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--modes", default="unsigned,signed",
                        help="comma-separated: unsigned, signed (default both)")
    args = parser.parse_args()
    modes = args.modes.split(",")
    if not set(modes) <= {"unsigned", "signed"}:
        parser.error("--modes: unsigned and/or signed")
    keys = ("achieved_rate_hz", "jitter_p50_ms", "jitter_p99_ms", "jitter_max_ms",
            "missed_ticks", "gcs_cpu_percent", "mock_cpu_percent")
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        key = new_key_file(Path(tmp) / "bench.key")
        costs = per_message_costs(key)
        for mode in modes:
            runs = [asyncio.run(one_run(args.vehicles, args.rate, args.duration,
                                        key if mode == "signed" else None))
                    for _ in range(args.repeat)]
            median = {k: statistics.median(r[k] for r in runs) for k in keys}
            results[mode] = {
                "median": median,
                "floor": {"jitter_p99_ms": 5.0, "missed_ticks": 0,
                          "met": median["jitter_p99_ms"] < 5.0
                          and all(r["missed_ticks"] == 0 for r in runs)},
                "runs": runs,
            }
    out = {
        "benchmark": "stream",
        "scenario": {"vehicles": args.vehicles, "rate_hz": args.rate,
                     "duration_s": args.duration, "repeat": args.repeat,
                     "mock": "separate process (fleetplan mock), UDP loopback"},
        "per_message_us": costs,
        **results,
        "machine": {"python": platform.python_version(), "platform": platform.platform(),
                    "cpus": os.cpu_count(), "processor": platform.processor() or None,
                    "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024},
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
