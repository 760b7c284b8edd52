"""Setpoint streaming benchmark: N mock vehicles in another process, one GCS process streaming.

Starts `fleetplan mock` (python -m gcs.cli.main mock) with N vehicles on free ports, connects
one `gcs.flight.link.hub.LinkHub`, and streams every vehicle a moving setpoint track through the
shared clock (`gcs.flight.timeline.stream.Streamer`) at RATE Hz for DURATION s. Prints one JSON
document: scenario, achieved rate, send-instant jitter p50/p99/max (lateness of each send against
its tick's scheduled instant), missed ticks, CPU of the GCS process and of the mock process, machine
info. With --repeat R it runs R times per mode and also reports the medians. Floor: p99 jitter
<= 2 ms with no missed tick, at the default stream priority (realtime; --priority normal to
compare).

Modes (--modes): ``unsigned``, and ``signed``: MAVLink 2 signing end to end (a fresh key is
provisioned on the mock vehicles with SETUP_SIGNING over a first, unsigned connection, then the
GCS reconnects signed; every setpoint is signed, every telemetry packet verified).

Telemetry (--telemetry): the mocks send ``minimal`` (~65 messages/s per vehicle) or ``px4``
(PX4's offboard link, ~410 messages/s per vehicle, `gcs.sim.telemetry`). --message-rates
``leave`` takes what they send; ``request`` first asks each vehicle for what the GCS reads
(MAV_CMD_SET_MESSAGE_INTERVAL, `gcs.autopilot.px4.Px4.message_rates`, the rest off). The GCS
decodes only the ids it reads and drops the rest before decoding (--decode needed, as the
flight executor does; --decode all to compare). Telemetry latency is the receive instant of
each LOCAL_POSITION_NED minus the mock's stamp (time_boot_ms, whose zero the mock prints on
the shared monotonic clock): it includes the mock's own loop, 1 ms steps. `stalls` counts
streamer wake-ups more than 2 ms late by cause (descheduled by the OS, or busy with this
process's own callbacks); `gc_collections` the garbage collections per generation.

It also reports the CPU cost per message in this process (`per_message_us`: encoding one
setpoint, receiving one LOCAL_POSITION_NED datagram, dropping one unread ATTITUDE datagram
before decoding, unsigned and signed; the minimum of 5 repeats, so it holds on a busy machine
where the jitter figures do not).

    python bench/stream.py                      # 100 vehicles, 50 Hz, 30 s, both modes
    python bench/stream.py --duration 5 --repeat 3 --modes signed
    python bench/stream.py --telemetry px4 --message-rates leave,request --modes unsigned
"""

from __future__ import annotations

import argparse
import asyncio
import gc
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

from gcs.autopilot.px4 import PX4
from gcs.flight.link.endpoints import UdpEndpoint
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import DECODED_IDS, VehicleLink
from gcs.flight.link.setpoints import Setpoint, SetpointTrack
from gcs.flight.link.signing import LinkSigning
from gcs.flight.procedure.vehicle import request_message_rates
from gcs.flight.timeline.stream import Streamer, jitter_stats
from gcs.sim.ports import free_udp_base
from gcs.wire import SigningKey, mavlink, new_key_file, signing_timestamp

#: The 100-vehicle, 50 Hz floor: p99 send lateness (ms), with no missed tick.
JITTER_P99_FLOOR_MS = 2.0


def _ordinary_priority() -> None:
    """In the mock's process: the ordinary scheduling class (a mock started from a real-time
    thread would inherit it; at --priority realtime only the GCS's loop runs real-time)."""
    if hasattr(os, "sched_setscheduler"):
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))


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
                  key: SigningKey | None = None, telemetry: str = "minimal",
                  message_rates: str = "leave", decode: str = "needed",
                  realtime: bool = False) -> dict:
    base = free_udp_base(range(2 * vehicles))
    mock = subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "mock", "--vehicles", str(vehicles),
         "--base-port", str(base), "--listen-base-port", str(base + vehicles),
         "--settle", "0", "--telemetry", telemetry], stdout=subprocess.PIPE, text=True,
        preexec_fn=_ordinary_priority)
    try:
        assert mock.stdout is not None
        # "mock: N PX4-like vehicles ...; time_boot_ms 0 at monotonic T" once it listens
        mock_boot = float(mock.stdout.readline().rsplit(" ", 1)[1])
        if key is not None:
            await provision(base, vehicles, key)
        async with LinkHub(decode_ids=DECODED_IDS if decode == "needed" else None) as hub:
            links = [await hub.add(f"v{i}", f"udpin:127.0.0.1:{base + i}", i + 1,
                                   signing_key=key)
                     for i in range(vehicles)]
            for link in links:
                if not await link.wait_for(lambda t: t.heartbeat_time is not None, 10.0):
                    raise RuntimeError(f"no heartbeat from {link.vehicle_id}")
            answers: list[dict[str, str]] = []
            if message_rates == "request":
                answers = await asyncio.gather(*(
                    request_message_rates(link, PX4.message_rates(30.0)) for link in links))
                await asyncio.sleep(0.5)  # what was sent before the requests
            latency: list[float] = []
            measuring = [False]

            def on_message(_link: VehicleLink, msg: object, now: float) -> None:
                # receive instant minus the mock's stamp (time_boot_ms, 1 ms steps)
                if measuring[0] and msg.get_type() == "LOCAL_POSITION_NED":  # type: ignore
                    latency.append(now - mock_boot - msg.time_boot_ms * 1e-3)  # type: ignore

            for link in links:
                link.listeners.append(on_message)
            # a circle of radius 1 m at 2 m altitude, one per vehicle
            ticks = int(duration * rate) + 1
            phase = np.arange(ticks) / rate
            pos = np.stack([np.cos(phase), np.sin(phase), np.full(ticks, -2.0)], axis=1)
            vel = np.stack([-np.sin(phase), np.cos(phase), np.zeros(ticks)], axis=1)
            acc = np.stack([-np.cos(phase), -np.sin(phase), np.zeros(ticks)], axis=1)
            track = SetpointTrack(pos, vel, acc, 0.0, rate)
            streamer = Streamer(rate, realtime=realtime)
            start = streamer.next_tick() + 1
            for link in links:
                streamer.assign(link.vehicle_id, link, track, start)
            streamer.measuring = True
            measuring[0] = True
            endpoints = list(hub.endpoints.values())
            received0 = sum(e.messages_received for e in endpoints)
            skipped0 = sum(e.skipped for e in endpoints)
            gc0 = [g["collections"] for g in gc.get_stats()]
            cpu0 = time.process_time()
            mock_cpu0 = proc_cpu_seconds(mock.pid)
            wall0 = time.monotonic()
            streamer.start()
            await asyncio.sleep(duration)
            await streamer.stop()
            wall = time.monotonic() - wall0
            cpu = time.process_time() - cpu0
            mock_cpu = proc_cpu_seconds(mock.pid) - mock_cpu0
            measuring[0] = False
            gc_runs = [g["collections"] - c for g, c in zip(gc.get_stats(), gc0, strict=True)]
            received = sum(e.messages_received for e in endpoints) - received0
            skipped = sum(e.skipped for e in endpoints) - skipped0
            sent = sum(link.setpoints_sent for link in links)
            dropped = sum(link.telemetry.security.total for link in links)
            lost = sum(link.telemetry.seq_lost for link in links)
            counted = sum(link.telemetry.seq_received for link in links)
            first_endpoint = links[0].endpoint.messages_received
    finally:
        mock.terminate()
        mock.wait(timeout=10)
    stats = jitter_stats(streamer.lateness)
    lat = np.asarray(latency) * 1000.0
    refused = sorted({f"{name} {answer}" for a in answers for name, answer in a.items()
                      if not answer.endswith("ACCEPTED")})
    return {
        "achieved_rate_hz": sent / vehicles / wall,
        **{k: round(v, 3) for k, v in stats.items()},
        "missed_ticks": streamer.missed_ticks,
        "stalls": dict(streamer.stalls),
        "gcs_scheduling": streamer.scheduling,
        "setpoints_sent": sent,
        "gcs_cpu_percent": round(100.0 * cpu / wall, 1),
        "mock_cpu_percent": round(100.0 * mock_cpu / wall, 1),
        "telemetry_per_s": round(received / wall),
        "telemetry_skipped_per_s": round(skipped / wall),
        "telemetry_latency_p50_ms": round(float(np.percentile(lat, 50)), 2) if lat.size else None,
        "telemetry_latency_p99_ms": round(float(np.percentile(lat, 99)), 2) if lat.size else None,
        "telemetry_latency_max_ms": round(float(lat.max()), 2) if lat.size else None,
        "link_loss_percent": round(100.0 * lost / max(1, lost + counted), 3),
        "rate_requests_refused": refused,
        "gc_collections": gc_runs,
        "telemetry_messages_received_first_endpoint": first_endpoint,
        "telemetry_dropped_by_security": dropped,
    }


def per_message_costs(key: SigningKey, count: int = 2000) -> dict:
    """Microseconds of CPU per setpoint encoded and per telemetry datagram received (parse,
    pinning, signature check, telemetry update), unsigned and signed; min of 5 repeats."""
    out: dict[str, dict[str, float]] = {"pack_setpoint": {}, "receive_position": {},
                                        "skip_attitude": {}}
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
                lambda e=endpoint, d=datagrams: e.received(next(d), ("127.0.0.1", 1)),
                number=count) / count)
        if link.telemetry.security.total:
            raise RuntimeError(f"{mode}: telemetry dropped {link.telemetry.security}")
        # an unread id (ATTITUDE) dropped before decoding: header, CRC, pinning, signature
        skipper = UdpEndpoint("udpin:127.0.0.1:9", DECODED_IDS)
        pinned = VehicleLink("v", skipper, 1, 1, signing=signing, peer=("127.0.0.1", 1))
        skips = []
        for _ in range(5):
            datagrams = iter([vehicle.attitude_encode(0, 0.1, 0.2, 0.3, 0, 0, 0).pack(vehicle)
                              for _ in range(count)])
            skips.append(timeit.timeit(
                lambda e=skipper, d=datagrams: e.received(next(d), ("127.0.0.1", 1)),
                number=count) / count)
        if pinned.telemetry.skipped != 5 * count:
            raise RuntimeError(f"{mode}: {pinned.telemetry.skipped} skipped of {5 * count}")
        out["skip_attitude"][mode] = round(min(skips) * 1e6, 1)
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
    parser.add_argument("--telemetry", choices=("minimal", "px4"), default="minimal",
                        help="what the mocks send: minimal (~65 messages/s each) or px4 "
                             "(PX4's offboard link, ~410 messages/s each)")
    parser.add_argument("--message-rates", default="leave",
                        help="comma-separated: leave (take what the vehicles send) and/or "
                             "request (MAV_CMD_SET_MESSAGE_INTERVAL for what the GCS reads, "
                             "the rest off); each is run")
    parser.add_argument("--decode", choices=("needed", "all"), default="needed",
                        help="needed: drop unread message ids before decoding, like the "
                             "flight executor (default); all: decode everything")
    parser.add_argument("--priority", choices=("realtime", "normal"), default="realtime",
                        help="the flights' stream_priority: realtime (the default, "
                             "Streamer(realtime=True): SCHED_RR 1 for the GCS's loop while "
                             "streaming, not the mock's; needs CAP_SYS_NICE or an rtprio "
                             "limit) or normal")
    args = parser.parse_args()
    rate_modes = args.message_rates.split(",")
    if not set(rate_modes) <= {"leave", "request"}:
        parser.error("--message-rates: leave and/or request")
    modes = args.modes.split(",")
    if not set(modes) <= {"unsigned", "signed"}:
        parser.error("--modes: unsigned and/or signed")
    keys = ("achieved_rate_hz", "jitter_p50_ms", "jitter_p99_ms", "jitter_max_ms",
            "missed_ticks", "gcs_cpu_percent", "mock_cpu_percent", "telemetry_per_s",
            "telemetry_latency_p50_ms", "telemetry_latency_p99_ms", "link_loss_percent")
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        key = new_key_file(Path(tmp) / "bench.key")
        costs = per_message_costs(key)
        for mode, rates in ((m, r) for m in modes for r in rate_modes):
            runs = [asyncio.run(one_run(args.vehicles, args.rate, args.duration,
                                        key if mode == "signed" else None, args.telemetry,
                                        rates, args.decode, args.priority == "realtime"))
                    for _ in range(args.repeat)]
            median = {k: statistics.median(r[k] for r in runs if r[k] is not None)
                      for k in keys}
            name = mode if rate_modes == ["leave"] else f"{mode}/{rates}"
            results[name] = {
                "median": median,
                "floor": {"jitter_p99_ms": JITTER_P99_FLOOR_MS, "missed_ticks": 0,
                          "met": median["jitter_p99_ms"] <= JITTER_P99_FLOOR_MS
                          and all(r["missed_ticks"] == 0 for r in runs)},
                "runs": runs,
            }
    out = {
        "benchmark": "stream",
        "scenario": {"vehicles": args.vehicles, "rate_hz": args.rate,
                     "duration_s": args.duration, "repeat": args.repeat,
                     "telemetry": args.telemetry, "decode": args.decode,
                     "stream_priority": args.priority,
                     "load_average_at_end": [round(x, 2) for x in os.getloadavg()],
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
