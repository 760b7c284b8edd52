"""Setpoint streaming benchmark: N mock vehicles in another process, one GCS process streaming.

Starts `fleetplan mock` (python -m gcs.cli.main mock) with N vehicles on free ports, connects
one `gcs.flight.link.LinkHub`, and streams every vehicle a moving setpoint track through the shared
clock (`gcs.flight.stream.Streamer`) at RATE Hz for DURATION s. Prints one JSON document: scenario,
achieved rate, send-instant jitter p50/p99/max (lateness of each send against its tick's
scheduled instant), CPU of the GCS process and of the mock process, machine info. With
--repeat R it runs R times and also reports the medians. Floor: p99 jitter < 5 ms.

    python bench/stream.py                      # 50 vehicles, 50 Hz, 30 s, 1 run
    python bench/stream.py --duration 5 --repeat 3
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
import time
from pathlib import Path

# Run as `python bench/stream.py`, this folder comes first on sys.path, where planner.py
# (the planner benchmark) would shadow the planner package: the project root goes first.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from gcs.flight.link import LinkHub
from gcs.flight.setpoints import SetpointTrack
from gcs.flight.stream import Streamer, jitter_stats
from gcs.sim.ports import free_udp_base


def proc_cpu_seconds(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


async def one_run(vehicles: int, rate: float, duration: float) -> dict:
    base = free_udp_base(range(2 * vehicles))
    mock = subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "mock", "--vehicles", str(vehicles),
         "--base-port", str(base), "--listen-base-port", str(base + vehicles),
         "--settle", "0"], stdout=subprocess.PIPE, text=True)
    try:
        assert mock.stdout is not None
        mock.stdout.readline()  # "mock: N PX4-like vehicles ..." once it listens
        async with LinkHub() as hub:
            links = [await hub.add(f"v{i}", f"udpin:127.0.0.1:{base + i}", i + 1)
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
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, default=50)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    runs = [asyncio.run(one_run(args.vehicles, args.rate, args.duration))
            for _ in range(args.repeat)]
    keys = ("achieved_rate_hz", "jitter_p50_ms", "jitter_p99_ms", "jitter_max_ms",
            "gcs_cpu_percent", "mock_cpu_percent")
    median = {k: statistics.median(r[k] for r in runs) for k in keys}
    out = {
        "benchmark": "stream",
        "scenario": {"vehicles": args.vehicles, "rate_hz": args.rate,
                     "duration_s": args.duration, "repeat": args.repeat,
                     "mock": "separate process (fleetplan mock), UDP loopback"},
        "median": median,
        "floor": {"jitter_p99_ms": 5.0, "met": median["jitter_p99_ms"] < 5.0},
        "runs": runs,
        "machine": {"python": platform.python_version(), "platform": platform.platform(),
                    "cpus": os.cpu_count(), "processor": platform.processor() or None,
                    "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024},
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
