"""Geofence upload benchmark: what giving every vehicle its fence adds before arming.

Starts N in-process mock vehicles (`gcs.sim.MockFleet`, PX4's mission protocol), links them
through one `gcs.flight.link.hub.LinkHub` as a flight does, and times
`gcs.flight.procedure.fence_upload.
send_fence` (upload, read back, compare) for every vehicle at once, with a fence of the
workspace plus P pillars (exclusion circles) placed per vehicle (`gcs.geofence`). Prints one
JSON document: the wall time of the whole fleet's upload (median and max over --repeat), items
per vehicle, the machine's load. Both ends share this process, so a busy machine slows both.

    python bench/geofence.py                       # 10 vehicles, 20 pillars, 5 repeats
    python bench/geofence.py --vehicles 50 --pillars 100
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import time
from pathlib import Path

# Run as `python bench/geofence.py`, this folder comes first on sys.path, where planner.py
# (the planner benchmark) would shadow the planner package: the project root goes first.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from gcs import frames
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import DECODED_IDS
from gcs.flight.procedure.fence_upload import send_fence
from gcs.geofence import build_fence, fence_items
from gcs.sim import MockFleet
from gcs.sim.ports import free_udp_base, mock_fleet_ports, mock_port_offsets


def _scenario(vehicles: int, pillars: int) -> dict:
    side = max(10.0, 2.0 * vehicles)
    rng = np.random.default_rng(1)
    centres = rng.uniform(1.0, side - 1.0, size=(pillars, 2))
    return {"limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [side, side, 5.0]},
            "obstacles": [{"id": f"p{k}", "cylinder": {"center": c.tolist(), "radius": 0.3,
                                                       "z": [0.0, 5.0]}}
                          for k, c in enumerate(centres)]}


async def _run(vehicles: int, pillars: int, repeat: int) -> dict:
    fence = build_fence(_scenario(vehicles, pillars))
    homes = [np.array([1.0 + 2.0 * i, 0.5, 0.0]) for i in range(vehicles)]
    base = free_udp_base(mock_port_offsets(vehicles))
    times = []
    async with (MockFleet(homes=homes, **mock_fleet_ports(base, vehicles)) as mock,
                LinkHub(decode_ids=DECODED_IDS) as hub):
        spec = mock.fleet_dict()["vehicles"]
        links = [await hub.add(v["id"], v["connection"], v["system_id"]) for v in spec]
        for link in links:
            if not await link.wait_for(lambda t: t.heartbeat_time is not None, 10.0):
                raise SystemExit(f"{link.vehicle_id}: no HEARTBEAT")
        items = [fence_items(fence, home, frames.enu_to_geodetic(home, mock.world_origin))
                 for home in homes]
        for _ in range(repeat):
            start = time.perf_counter()
            await asyncio.gather(*(send_fence(link, its)
                                   for link, its in zip(links, items, strict=True)))
            times.append(time.perf_counter() - start)
    return {"vehicles": vehicles, "pillars": pillars, "items_per_vehicle": len(items[0]),
            "fleet_upload_s_median": round(statistics.median(times), 4),
            "fleet_upload_s_max": round(max(times), 4), "repeat": repeat,
            "loadavg": os.getloadavg(), "cpus": os.cpu_count()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, default=10)
    parser.add_argument("--pillars", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    print(json.dumps(asyncio.run(_run(args.vehicles, args.pillars, args.repeat)), indent=2))


if __name__ == "__main__":
    main()
