"""`fleetplan mock`: run N PX4-like mock vehicles (gcs.sim) until interrupted.

Vehicle i listens on UDP --listen-base-port + i and sends to --base-port + i on 127.0.0.1
(PX4 SITL's offboard ports by default, `gcs.autopilot.px4`), system id i + 1. Homes: under
the starts of --plan, or a row --spacing metres apart along x. --fleet-out writes the matching
fleet file.
--realism px4 makes them behave like PX4 v1.16 SIH SITL (noisy wandering estimate, attitude lag,
late boot, arming refused for 3.5 s: `MockConfig.px4_like`); the default is ideal.
--gcs-port PORT gives every vehicle a second, PX4-like GCS link sending to 127.0.0.1:PORT
(QGroundControl and MAVProxy listen on 14550), so a ground station can watch them.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from gcs.autopilot import px4
from gcs.cli import mock_timings
from gcs.sim.realism import REALISMS

if TYPE_CHECKING:
    from gcs.sim import MockFleet

__all__ = ["configure", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--vehicles", "-n", type=int, default=None,
                        help="number of vehicles (default: the plan's, else 4)")
    parser.add_argument("--plan", help="put the homes under this plan's starts (Plan JSON)")
    parser.add_argument("--spacing", type=float, default=2.0,
                        help="without --plan: homes this far apart along x (m, default 2)")
    parser.add_argument("--base-port", type=int, default=px4.OFFBOARD_GCS_BASE_PORT,
                        help="vehicle i sends to this port + i (default %(default)s)")
    parser.add_argument("--listen-base-port", type=int, default=None,
                        help=f"vehicle i listens on this port + i (default "
                             f"{px4.OFFBOARD_VEHICLE_BASE_PORT}; a fleet of N > "
                             f"{px4.OFFBOARD_VEHICLE_BASE_PORT - px4.OFFBOARD_GCS_BASE_PORT}: "
                             f"{px4.OFFBOARD_GCS_BASE_PORT} + N, past its GCS ports)")
    parser.add_argument("--max-port-offset", type=int, default=None,
                        help="vehicles from this index on share one GCS port, like PX4 SITL "
                             "from instance 10 on (9); 0 puts the whole fleet on one port")
    parser.add_argument("--realism", choices=REALISMS, default="ideal",
                        help="ideal (exact state, default) or px4: PX4 SIH SITL's estimate "
                             "noise, tracking lag and timings")
    parser.add_argument("--autopilot", default="px4",
                        help="whose rules the vehicles follow: px4 (default) or ardupilot "
                             "(ArduCopter 4.7: GUIDED, NAV_TAKEOFF, PreArm texts, streams only "
                             "on request), or one per vehicle, comma-separated "
                             "(px4,ardupilot,...: a mixed fleet)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the noise and injected loss (default 0)")
    parser.add_argument("--settle", type=float, default=None,
                        help="arming is TEMPORARILY_REJECTED this long after start (s, default "
                             "5 for ideal, 3.5 for px4, as PX4 SITL)")
    mock_timings.add_flags(parser)
    parser.add_argument("--position-rate", type=float, default=30.0,
                        help="LOCAL_POSITION_NED rate (Hz, default 30)")
    parser.add_argument("--telemetry", choices=("minimal", "px4"), default=None,
                        help="what the vehicles send: minimal (about 65 messages/s each, the "
                             "default for ideal) or px4 (PX4's offboard-link set and rates, "
                             "about 410 messages/s each; the default for --realism px4)")
    parser.add_argument("--loss", type=float, default=0.0,
                        help="fault: fraction of packets dropped each way (0..1)")
    parser.add_argument("--delay", type=float, default=0.0,
                        help="fault: seconds added to every packet")
    parser.add_argument("--gcs-port", type=int, default=None,
                        help="also give every vehicle a GCS link sending to this port, like "
                             "PX4's (QGroundControl and MAVProxy listen on 14550; default: none)")
    parser.add_argument("--fleet-out", help="write the fleet file for these vehicles here")
    parser.add_argument("--position-error", type=float, default=None,
                        help="state this position_error (m) in the --fleet-out file (e.g. 0.25 "
                             "for --realism px4)")
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many seconds (default: run until Ctrl-C)")


def run(args: argparse.Namespace) -> int:
    """Run the mock fleet of `args` until interrupted or `--duration`; the exit status."""
    import asyncio
    import sys

    from gcs.sim.ports import listen_offset
    if isinstance(placed := _plan_homes(args), str):
        print(f"error: {placed}", file=sys.stderr)
        return 2
    homes, ids = placed
    count = len(homes) if homes is not None else (4 if args.vehicles is None else args.vehicles)
    if args.listen_base_port is None:  # PX4 SITL's, or past the usual GCS block of a larger fleet
        args.listen_base_port = px4.OFFBOARD_GCS_BASE_PORT + listen_offset(count)
    if isinstance(checked := _checked_flags(args, count), str):
        print(f"error: {checked}", file=sys.stderr)
        return 2
    timings, autopilots = checked
    if homes is None:
        homes = [[args.spacing * i, 0.0, 0.0] for i in range(count)]
    return asyncio.run(_serve(args, homes, ids, timings, autopilots))


def _plan_homes(args: argparse.Namespace
                ) -> tuple[list[list[float]] | None, list[str] | None] | str:
    """(homes, ids) under --plan's starts, (None, None) without --plan, or what is wrong."""
    if not args.plan:
        return None, None
    from gcs.cli.plan_file import read_plan
    from gcs.sim import homes_under

    try:
        plan = read_plan(args.plan, "mock --plan")
    except ValueError as exc:
        return str(exc)
    homes = homes_under(plan.scenario.starts)
    if args.vehicles is not None and args.vehicles != len(homes):
        return f"--vehicles {args.vehicles} but the plan has {len(homes)}"
    return homes, plan.scenario.ids


def _checked_flags(args: argparse.Namespace, count: int
                   ) -> tuple[dict[str, float], list[str]] | str:
    """(the timings, the autopilots given) from the flags of a fleet of `count`, or what is
    wrong with them (the first found): checked before any vehicle starts."""
    import math

    from gcs.cli.hints import block_error, port_error
    from gcs.sim.config import AUTOPILOTS
    for name in ("settle", "position_rate", "position_error"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value >= 0.0):
            return f"--{name.replace('_', '-')} must be a finite number >= 0, got {value}"
    if not 0 <= args.seed < 2**32:
        return f"--seed must be an integer in [0, 2^32), got {args.seed}"
    if args.position_error is not None and args.position_error > 10.0:
        return f"--position-error must be within [0, 10] m, got {args.position_error}"
    try:
        timings = mock_timings.chosen(args)
    except ValueError as exc:
        return str(exc)
    if not args.position_rate > 0.0:
        return "--position-rate must be above 0"
    if not 1 <= count <= 254:  # MAVLink system ids 1..254 (255 is the GCS's)
        return f"--vehicles must be between 1 and 254, got {count}"
    for bad_port in (port_error("--gcs-port", args.gcs_port),
                     block_error("--base-port", args.base_port, count),
                     block_error("--listen-base-port", args.listen_base_port, count)):
        if bad_port is not None:
            return bad_port
    if not (math.isfinite(args.loss) and 0.0 <= args.loss <= 1.0):
        return f"--loss must be a fraction within [0, 1], got {args.loss}"
    if not (math.isfinite(args.delay) and args.delay >= 0.0):
        return f"--delay must be a finite number of seconds >= 0, got {args.delay}"
    autopilots = [a.strip() for a in args.autopilot.split(",")]
    bad = [a for a in autopilots if a not in AUTOPILOTS]
    if bad or len(autopilots) not in (1, count):
        return (f"--autopilot must be {' or '.join(AUTOPILOTS)}, or one of them per "
                f"vehicle ({count}) separated by commas, got {args.autopilot!r}")
    return timings, autopilots


def _mock_fleet(args: argparse.Namespace, homes: list[list[float]], timings: dict[str, float],
                autopilots: list[str]) -> MockFleet:
    """The mock fleet the flags describe (not started), with its injected faults."""
    from gcs.sim import MockConfig, MockFleet

    config = MockConfig.preset(args.realism, position_rate=args.position_rate,
                               seed=args.seed, **timings)
    if args.settle is not None:
        config.settle_time = args.settle
    if args.telemetry is not None:
        config.telemetry_profile = args.telemetry
    mock = MockFleet(homes=homes, gcs_base_port=args.base_port,
                     listen_base_port=args.listen_base_port,
                     max_port_offset=args.max_port_offset, config=config,
                     gcs_link_port=args.gcs_port, autopilots=autopilots)
    for vehicle in mock.vehicles:
        vehicle.faults.loss = args.loss
        vehicle.faults.delay = args.delay
    return mock


async def _serve(args: argparse.Namespace, homes: list[list[float]], ids: list[str] | None,
                 timings: dict[str, float], autopilots: list[str]) -> int:
    """Start the mock fleet, write --fleet-out, say where it listens, and run it until
    SIGINT, SIGTERM or --duration; the exit status."""
    import asyncio
    import json
    import signal
    import sys
    from pathlib import Path

    from gcs.cli.hints import port_in_use_hint
    count = len(homes)
    mock = _mock_fleet(args, homes, timings, autopilots * count if len(autopilots) == 1
                       else autopilots)
    try:
        await mock.start()
    except OSError as exc:  # a busy port: one line, not a traceback
        print(f"error: {exc}{port_in_use_hint(exc, '--base-port and --listen-base-port')}",
              file=sys.stderr)
        return 2
    if args.fleet_out:
        fleet = mock.fleet_dict(ids)
        if args.position_error is not None:
            fleet["position_error"] = args.position_error
        Path(args.fleet_out).write_text(json.dumps(fleet, indent=1))
    kinds = {"px4": "PX4-like", "ardupilot": "ArduCopter-like"}
    label = kinds[autopilots[0]] if len(set(autopilots)) == 1 else "PX4- and ArduCopter-like"
    print(f"mock: {count} {label} vehicles ({args.realism}), listening on "
          f"{args.listen_base_port}..{args.listen_base_port + count - 1}, sending to "
          f"{mock.vehicles[0].gcs_port}..{mock.vehicles[-1].gcs_port}; time_boot_ms 0 "
          f"at monotonic {mock.boot_monotonic:.6f}", flush=True)
    if args.gcs_port is not None:
        print(f"mock: GCS links send to 127.0.0.1:{args.gcs_port} (QGroundControl, "
              f"MAVProxy --master=udpin:127.0.0.1:{args.gcs_port})", flush=True)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    try:
        if args.duration is not None:
            await asyncio.wait_for(stop.wait(), args.duration)
        else:
            await stop.wait()
    except TimeoutError:
        pass
    finally:
        await mock.stop()
    accepted = sum(v.setpoints_accepted for v in mock.vehicles)
    print(f"mock: stopped after {mock.now():.1f} s; {accepted} setpoints accepted, "
          f"{mock.physics_steps} physics steps", flush=True)
    return 0
