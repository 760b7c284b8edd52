"""The chaos benchmark: flights on mock vehicles through faulty radio links and a killed
ground station; prints one JSON document to stdout.

    python bench/chaos.py                       # every case, once
    python bench/chaos.py --case loss20_after --runs 3
    python bench/chaos.py --vehicles 8          # paper-circle8 instead of paper-circle4

Each case plans the paper's circle (`planner/examples/paper-circle{4,8}.json`, 12 s, R = 1 m)
and flies it on in-process mocks whose every datagram passes a `gcs.sim.proxy.ChaosProxy`
(loss, delay, jitter, blackholes per vehicle, on a schedule). The station is the in-process
`FlightExecutor`, or for ``kill_fly`` a `fleetplan fly` process killed with SIGKILL at flight
time 4 s. Per run: the outcome (completed, or the error it ended on), the closest true
approach of any two vehicles (the mocks' own positions sampled every 10 ms until every vehicle
is down and disarmed, or `TAIL_S` after the end of the flight) against R, and what the record
kept (its events of note, the link figures, a `fly` record file).

Cases: ``none``; ``loss20_start`` (20 % both ways from the first datagram); ``loss20_after``
(from flight time 1 s); ``jitter`` (100-300 ms, nothing lost); ``blackhole_land_all`` (uav2's
link dead for 10 s from flight time 4 s, policy land_all); ``kill_fly``. Progress goes to
stderr.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import planner  # noqa: E402
from gcs.autopilot import px4  # noqa: E402
from gcs.fleet.fleetfile import FleetSpec, FlightOptions  # noqa: E402
from gcs.flight.run.executor import FlightExecutor  # noqa: E402
from gcs.sim import MockFleet, homes_under  # noqa: E402
from gcs.sim.proxy import ChaosProxy, LinkFaults  # noqa: E402

EXAMPLES = ROOT / "planner" / "examples"
#: The mock lands at 1 m/s and disarms 0.5 s after touchdown (PX4 parameters it mimics).
MOCK = {"land_speed": 1.0, "disarm_after_land": 0.5, "status_rate": 5.0}
OPTIONS = FlightOptions(hold_at_goal=1.0, prestream=0.3, climb_speed=2.0, land_speed=1.0)
#: How long the truth is sampled after the flight ended while a vehicle is still armed (s):
#: a fleet left holding stays where it is.
TAIL_S = 15.0
#: Events the table counts (the rest are in the record).
NOTED = ("link_degraded", "link_recovered", "fault", "abort", "landing_plan",
         "landing_fallback", "geofence", "geofence_retry", "command_refused", "separation_alarm")
#: (name, faults from the start, schedule [(flight time s, vehicle index or None, changes)],
#: policy).
CASES: dict[str, tuple[LinkFaults, list[tuple[float, int | None, dict[str, Any]]], str]] = {
    "none": (LinkFaults(), [], "hold_all"),
    "loss20_start": (LinkFaults(loss=0.2), [], "hold_all"),
    "loss20_after": (LinkFaults(), [(1.0, None, {"loss": 0.2})], "hold_all"),
    "jitter": (LinkFaults(delay=0.1, jitter=0.2), [], "hold_all"),
    "blackhole_land_all": (LinkFaults(), [(4.0, 1, {"blackhole": True}),
                                          (14.0, 1, {"blackhole": False})], "land_all"),
    "kill_fly": (LinkFaults(), [], "hold_all"),
}


def _plan(vehicles: int) -> planner.Plan:
    data = json.loads((EXAMPLES / f"paper-circle{vehicles}.json").read_text())
    plan = planner.plan(planner.Scenario.from_dict({**data, "steps": 60}))
    if not plan.ok:
        raise SystemExit(f"paper-circle{vehicles} did not plan: {plan.status}")
    return plan


def _closest(samples: list[np.ndarray], scale: np.ndarray) -> float:
    """Closest approach of any two vehicles over the samples ((N, 3) each), in R's metric."""
    truth = np.stack(samples) / scale  # (T, N, 3)
    i, j = np.triu_indices(truth.shape[1], k=1)
    return float(np.linalg.norm(truth[:, i] - truth[:, j], axis=2).min())


async def _watch(mock: MockFleet, done: Any, samples: list[np.ndarray]) -> None:
    """Sample the true positions every 10 ms until `done()` and every vehicle is down."""
    tail = None
    while True:
        samples.append(np.array([v.true_position_world for v in mock.vehicles]))
        if done():
            tail = tail or time.monotonic()
            if not any(v.armed for v in mock.vehicles) or time.monotonic() - tail > TAIL_S:
                return
        await asyncio.sleep(0.01)


async def _schedule(proxy: ChaosProxy, flight_time: Any,
                    steps: list[tuple[float, int | None, dict[str, Any]]]) -> None:
    for at, index, changes in sorted(steps, key=lambda s: s[0]):
        while (flight_time() or -1.0) < at:
            await asyncio.sleep(0.02)
        proxy.set(index, **changes)


async def _executor_case(plan: planner.Plan, case: str, seed: int) -> dict[str, Any]:
    faults, steps, policy = CASES[case]
    homes = homes_under(plan.scenario.starts)
    proxy, ports = ChaosProxy.on_free_ports(len(homes), seed=seed, faults=faults)
    async with proxy, MockFleet(homes=homes, settle_time=0.5, seed=seed, **ports,
                                **MOCK) as mock:
        fleet = FleetSpec.from_dict(proxy.fleet_dict(mock.fleet_dict(plan.scenario.ids)))
        flight = FlightExecutor(plan, fleet, OPTIONS.replace(policy=policy))
        task = flight.start()
        samples: list[np.ndarray] = []
        scheduler = asyncio.ensure_future(_schedule(proxy, flight.flight_time, steps))
        await _watch(mock, task.done, samples)
        scheduler.cancel()
        try:
            await task
            outcome = "ran to its end"
        except Exception as exc:
            outcome = f"{type(exc).__name__}: {exc}"
        record = flight.record
        assert record is not None
        kinds = [e["kind"] for e in record["events"]]
        degraded = [f"{e['vehicle']}: {e['detail']}" for e in record["events"]
                    if e["kind"] == "link_degraded"]
        return {"outcome": outcome, "completed": record["summary"]["completed"],
                "closest_m": round(_closest(samples, plan.scenario.separation_scale), 3),
                "record": {"events": {k: kinds.count(k) for k in NOTED if k in kinds},
                           "link_degraded": degraded[:2],
                           "link_quality": {vid: {k: q[k] for k in (
                               "loss_pct", "reordered", "latency_ms", "jitter_ms")}
                               for vid, q in record["summary"]["link_quality"].items()}}}


async def _kill_fly_case(plan: planner.Plan, seed: int) -> dict[str, Any]:
    """`fleetplan fly` in its own process, killed with SIGKILL at flight time 4 s."""
    homes = homes_under(plan.scenario.starts)
    proxy, ports = ChaosProxy.on_free_ports(len(homes), seed=seed)
    with tempfile.TemporaryDirectory() as tmp:
        plan_path, fleet_path = Path(tmp) / "plan.json", Path(tmp) / "fleet.json"
        record_path = Path(tmp) / "record.json"
        plan_path.write_text(json.dumps(plan.to_dict()))
        async with proxy, MockFleet(homes=homes, settle_time=0.5, seed=seed, **ports,
                                    **MOCK) as mock:
            fleet_path.write_text(json.dumps(proxy.fleet_dict(mock.fleet_dict(
                plan.scenario.ids))))
            fly = await asyncio.create_subprocess_exec(
                sys.executable, "-m", "gcs.cli.main", "fly", str(plan_path), "--fleet",
                str(fleet_path), "--record", str(record_path), "--quiet",
                "--hold-at-goal", "1", "--climb-speed", "2",
                stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.DEVNULL,
                cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
            samples: list[np.ndarray] = []
            killed: list[float] = []

            def done() -> bool:
                return bool(killed) or fly.returncode is not None

            async def kill() -> None:
                # flight time 4 s: every vehicle has been at its start for about 4 s
                while not all(v.armed and v.position_ned[2] < -0.5 for v in mock.vehicles):
                    await asyncio.sleep(0.05)
                await asyncio.sleep(4.0 + 1.0)  # the start tolerance's wait, then 4 s
                fly.send_signal(signal.SIGKILL)
                killed.append(time.monotonic())

            killer = asyncio.ensure_future(kill())
            await _watch(mock, done, samples)
            killer.cancel()
            await fly.wait()
            kept = "none"
            if record_path.exists():
                try:
                    document = json.loads(record_path.read_text())
                    kept = f"{len(document.get('events', []))} events"
                except ValueError:
                    kept = "unreadable"
        return {"outcome": f"fly killed (exit {fly.returncode})",
                "completed": False,
                "closest_m": round(_closest(samples, plan.scenario.separation_scale), 3),
                "landed": sum(int(not v.armed and v.position_ned[2] > -0.05)
                              for v in mock.vehicles),
                "hovering": sum(int(v.armed and v.mode == px4.HOLD) for v in mock.vehicles),
                "record": {"file": kept}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=sorted(CASES), action="append",
                        help="a case to run (repeat; default: every case)")
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--vehicles", type=int, choices=(4, 8), default=4)
    args = parser.parse_args()
    plan = _plan(args.vehicles)
    r = float(plan.scenario.min_separation)
    results = []
    for case in args.case or list(CASES):
        for run in range(args.runs):
            print(f"{case} run {run + 1}/{args.runs}", file=sys.stderr)
            seed = 100 + run
            if case == "kill_fly":
                result = asyncio.run(_kill_fly_case(plan, seed))
            else:
                result = asyncio.run(_executor_case(plan, case, seed))
            result.update(case=case, run=run, held=bool(result["closest_m"] >= r - 0.05))
            print(json.dumps(result), file=sys.stderr)
            results.append(result)
    print(json.dumps({"plan": f"paper-circle{args.vehicles}", "R_m": r,
                      "load_average": [round(x, 2) for x in os.getloadavg()],
                      "cases": results}, indent=1))


if __name__ == "__main__":
    main()
