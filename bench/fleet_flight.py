"""Fly a fleet file's vehicles (PX4, SITL or real) with `fleetplan fly`, case by case, under
hostile traffic or machine load, and measure each flight from the record and from outside.

It flies what the user flies: ``fleetplan fly PLAN --fleet FLEET --record ...`` in a process
of its own. Cases (comma-separated ``--cases``):

- ``quiet``: nothing else runs;
- ``raw`` / ``mavsdk``: `tests/flight/rejected_commands.py` sends every vehicle's `peer`
  40 unsigned LAND / force-DISARM commands a second (``mavsdk``: with its unsigned GCS
  HEARTBEAT and retransmissions), started once every vehicle has connected;
- ``hogs``: two busy-looping processes, no attacker (the machine's load alone);
- ``first``: ``raw``, started before ``--before-flight`` (which should boot the vehicles), so
  that its datagrams are the first the vehicles hear.

``--before-flight CMD`` runs a shell command before each flight (for SITL: restart the
vehicles); each line it prints that is a number is taken as the PID of a vehicle process,
whose CPU time (utime + stime from /proc) over the flight is reported. ``--truth PORTS``
(one UDP port per fleet vehicle, in order) listens for each vehicle's HIL_STATE_QUATERNION
(what PX4 SITL's SIH sends its display link, 19410 + instance): the vehicles' true positions,
placed at their fleet-file homes from where each was first heard, give the separation flown
independently of the estimate, and the simulated clock against the wall clock gives the
simulation's speed.

    python bench/fleet_flight.py PLAN.json FLEET.json --cases quiet,raw,hogs --repeats 2 \\
        --before-flight ./restart-vehicles.sh --truth 19410,19411,19412,19413 -o out.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shlex
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

os.environ.setdefault("MAVLINK20", "1")

import numpy as np
import pymap3d
from pymavlink.dialects.v20 import common as mavlink

from gcs.fleet.fleetfile import FleetSpec

ROOT = Path(__file__).resolve().parents[1]
CASES = ("quiet", "raw", "mavsdk", "hogs", "first")
RATE = 40.0
HOG = "while True: pass"
CONNECTED = re.compile(r"\] (\S+): connected ")
AIRBORNE_M = 0.5
"""A vehicle counts as airborne for the true separation this far above where it was first
heard (m)."""


def cpu_seconds(pid: int) -> float | None:
    """utime + stime of a process (s), or None once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class Truth(threading.Thread):
    """Each vehicle's HIL_STATE_QUATERNION on its own UDP port: true position and sim time."""

    def __init__(self, ports: list[int]) -> None:
        super().__init__(daemon=True)
        self.socks = []
        for port in ports:
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            s.bind(("127.0.0.1", port))
            s.setblocking(False)  # run() drains each socket without waiting
            self.socks.append(s)
        self.samples: list[list[tuple[float, float, float, float]]] = [[] for _ in ports]
        self.clock: list[list[tuple[float, float]]] = [[] for _ in ports]
        self.stop = threading.Event()

    def run(self) -> None:
        parsers = [mavlink.MAVLink(None) for _ in self.socks]
        for p in parsers:
            p.robust_parsing = True
        while not self.stop.is_set():
            for i, s in enumerate(self.socks):
                while True:
                    try:
                        data = s.recv(65536)
                    except OSError:
                        break
                    now = time.time()
                    try:
                        msgs = parsers[i].parse_buffer(data) or []
                    except mavlink.MAVError:
                        continue
                    for m in msgs:
                        if m.get_type() == "HIL_STATE_QUATERNION":
                            self.samples[i].append((now, m.lat * 1e-7, m.lon * 1e-7,
                                                    m.alt * 1e-3))
                        elif m.get_type() == "HIL_ACTUATOR_CONTROLS":  # its time is SIH's
                            self.clock[i].append((now, m.time_usec * 1e-6))
            time.sleep(0.005)

    def close(self) -> None:
        self.stop.set()
        self.join(2)
        for s in self.socks:
            s.close()

    def figures(self, homes: list[list[float]], t0: float, t1: float) -> dict[str, Any]:
        """True minimum separation while airborne (homes placed as the fleet file says), and
        the simulation's speed (sim seconds per wall second) over [t0, t1]."""
        tracks = []
        speeds: list[float] = []
        slowest: list[float] = []
        for home, samples, clock in zip(homes, self.samples, self.clock, strict=True):
            if len(samples) < 2:
                return {"true_min_separation_m": None, "sim_speed": None,
                        "sim_speed_slowest_1s": None}
            a = np.array(samples)
            lat0, lon0, alt0 = a[0, 1:4]
            e, n, u = pymap3d.geodetic2enu(a[:, 1], a[:, 2], a[:, 3], lat0, lon0, alt0)
            tracks.append((a[:, 0], np.column_stack([e, n, u]) + np.asarray(home)))
            c = np.array(clock) if clock else np.zeros((0, 2))
            w = (c[:, 0] >= t0) & (c[:, 0] <= t1) if len(c) else np.zeros(0, bool)
            if w.sum() > 2:
                speeds.append((c[w, 1][-1] - c[w, 1][0]) / (c[w, 0][-1] - c[w, 0][0]))
                edges = np.arange(c[w, 0][0], c[w, 0][-1], 1.0)
                wall = np.interp(edges, c[w, 0], c[w, 0])
                sim = np.interp(edges, c[w, 0], c[w, 1])
                if len(edges) > 1:
                    slowest.append(float(np.min(np.diff(sim) / np.diff(wall))))
        grid = np.arange(max(t[0][0] for t in tracks), min(t[0][-1] for t in tracks), 0.02)
        pos = [np.column_stack([np.interp(grid, t, p[:, k]) for k in range(3)])
               for t, p in tracks]
        best = math.inf
        for i in range(len(pos)):
            for j in range(i + 1, len(pos)):
                up = (pos[i][:, 2] > homes[i][2] + AIRBORNE_M) & (
                    pos[j][:, 2] > homes[j][2] + AIRBORNE_M)
                if up.any():
                    best = min(best, float(np.linalg.norm(pos[i][up] - pos[j][up], axis=1).min()))
        return {"true_min_separation_m": None if math.isinf(best) else round(best, 3),
                "sim_speed": [round(float(s), 3) for s in speeds],
                "sim_speed_slowest_1s": [round(s, 3) for s in slowest]}


def _attacker(fleet: FleetSpec, style: str) -> subprocess.Popen[str]:
    targets = ",".join(f"{v.peer[0]}:{v.peer[1]}={v.system_id}" for v in fleet.vehicles
                       if v.peer is not None)
    proc = subprocess.Popen(
        [sys.executable, "-m", "tests.flight.rejected_commands", "--vehicles", targets,
         "--rate", str(RATE), "--duration", "600", "--style", style], cwd=ROOT,
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    assert json.loads(proc.stdout.readline()) == {"ready": True}
    return proc


def _finish_attacker(proc: subprocess.Popen[str]) -> dict[str, Any]:
    out, _ = proc.communicate("", timeout=30)
    return json.loads(out.strip().splitlines()[-1])


def fly(case: str, plan: Path, fleet_path: Path, fleet: FleetSpec, args: argparse.Namespace,
        record: Path) -> dict[str, Any]:
    """One flight of `case`; its figures."""
    attacker = _attacker(fleet, "raw") if case == "first" else None
    pids: list[int] = []
    if args.before_flight:
        out = subprocess.run(args.before_flight, shell=True, check=True, text=True,
                             stdout=subprocess.PIPE).stdout
        pids = [int(line) for line in out.split() if line.isdigit()]
    truth = Truth(args.truth) if args.truth else None
    if truth is not None:
        truth.start()
    hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(
        2 if case == "hogs" else 0)]
    cpu0 = {pid: cpu_seconds(pid) for pid in pids}
    load0 = os.getloadavg()
    t0 = time.time()
    cmd = [sys.executable, "-m", "gcs.cli.main", "fly", str(plan), "--fleet", str(fleet_path),
           "--record", str(record), *shlex.split(args.fly_args)]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    assert proc.stdout is not None
    lines = []
    connected: set[str] = set()
    attacked_at = None
    for line in proc.stdout:
        lines.append(line.rstrip())
        m = CONNECTED.search(line)
        if m:
            connected.add(m.group(1))
            if case in ("raw", "mavsdk") and attacker is None and len(connected) == len(
                    fleet.vehicles):
                attacker = _attacker(fleet, case)
                attacked_at = time.time() - t0
    proc.wait()
    t1 = time.time()
    cpu1 = {pid: cpu_seconds(pid) for pid in pids}
    load1 = os.getloadavg()
    for hog in hogs:
        hog.kill()
        hog.wait()
    report = _finish_attacker(attacker) if attacker is not None else None
    if truth is not None:
        truth.close()
    out: dict[str, Any] = {"case": case, "exit": proc.returncode, "wall_s": round(t1 - t0, 1),
                           "vehicle_cpu_share": None,
                           "attacker_started_s": attacked_at,
                           "load_average_before": [round(x, 2) for x in load0],
                           "load_average_after": [round(x, 2) for x in load1],
                           "vehicle_cpu_s": [round(cpu1[p] - cpu0[p], 2)
                                             if cpu1[p] is not None and cpu0[p] is not None
                                             else None for p in pids],
                           "attacker": report, "tail": lines[-12:]}
    cpu = [c for c in out["vehicle_cpu_s"] if c is not None]
    if cpu:  # CPU seconds per wall second of the flight, per vehicle process
        out["vehicle_cpu_share"] = round(statistics.mean(cpu) / (t1 - t0), 3)
    if record.exists():
        rec = json.loads(record.read_text())
        s = rec["summary"]
        out.update({k: s.get(k) for k in (
            "completed", "why", "setpoint_rate_hz", "missed_ticks", "jitter_p50_ms",
            "jitter_p99_ms", "tracking_error_max", "min_separation_measured",
            "min_separation_required", "separation_alarm_at", "goal_error_max")})
        out["security"] = s.get("security")
        out["events"] = [f"{e['vehicle']}: {e['kind']} {e['detail']}" for e in rec["events"]
                         if e["kind"] in ("separation_alarm", "fault", "abort", "error",
                                          "dropped_packets", "station_stall")][:12]
    if truth is not None:
        out.update(truth.figures([list(v.home) if v.home is not None else [0, 0, 0]
                                  for v in fleet.vehicles], t0, t1))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("plan", type=Path)
    parser.add_argument("fleet", type=Path)
    parser.add_argument("--cases", default="quiet,raw,mavsdk,hogs")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--before-flight", default="", help="shell command run before each "
                        "flight; numbers it prints are vehicle PIDs")
    parser.add_argument("--truth", type=lambda s: [int(p) for p in s.split(",")], default=None,
                        help="UDP ports of each vehicle's HIL_STATE_QUATERNION, fleet order")
    parser.add_argument("--fly-args", default="", help="extra `fleetplan fly` arguments")
    parser.add_argument("-o", "--output", type=Path, help="write the JSON here too")
    parser.add_argument("--records", type=Path, help="keep each flight's record in this "
                        "folder (CASE-N.json)")
    args = parser.parse_args()
    cases = args.cases.split(",")
    unknown = sorted(set(cases) - set(CASES))
    if unknown:
        parser.error(f"--cases: unknown {', '.join(unknown)} (known: {', '.join(CASES)})")
    fleet = FleetSpec.from_dict(json.loads(args.fleet.read_text()), args.fleet.parent)
    flights: dict[str, list[dict[str, Any]]] = {c: [] for c in cases}
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.records or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for k in range(args.repeats):  # interleaved: the machine's load drifts
            for case in cases:
                f = fly(case, args.plan, args.fleet, fleet, args, folder / f"{case}-{k}.json")
                print(json.dumps({key: f.get(key) for key in (
                    "case", "completed", "setpoint_rate_hz", "missed_ticks", "jitter_p99_ms",
                    "min_separation_measured", "true_min_separation_m", "goal_error_max",
                    "sim_speed", "sim_speed_slowest_1s", "vehicle_cpu_share",
                    "load_average_before")}), file=sys.stderr,
                      flush=True)
                flights[case].append(f)
    summary = {}
    for case, fs in flights.items():
        def med(key: str, fs: list[dict[str, Any]] = fs) -> float | None:
            vals = [f[key] for f in fs if isinstance(f.get(key), (int, float))]
            return round(statistics.median(vals), 3) if vals else None
        summary[case] = {"flights": len(fs), "completed": sum(bool(f.get("completed"))
                                                               for f in fs),
                         **{k: med(k) for k in ("setpoint_rate_hz", "missed_ticks",
                                                "jitter_p99_ms", "min_separation_measured",
                                                "true_min_separation_m", "goal_error_max",
                                                "vehicle_cpu_share")}}
    out = {"cpus": os.cpu_count(), "rate_per_vehicle": RATE, "summary": summary,
           "flights": flights}
    text = json.dumps(out, indent=1)
    if args.output:
        args.output.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
