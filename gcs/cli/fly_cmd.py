"""`fleetplan fly PLAN.json --fleet FLEET.json | --mock`: fly a plan and record the flight.

Live progress per vehicle once a second and every event as it happens; a summary at the end;
exit status 0 only when the flight completed. Ctrl-C aborts safely: every vehicle lands and
the command waits for them to disarm (a second Ctrl-C exits at once). SIGUSR1 pauses the
flight (the clock stops, every vehicle holds the plan's setpoint of the same plan time),
SIGUSR2 resumes it: ``kill -USR1 PID``. With ``--control PATH`` the flight also takes commands
on a unix socket (`gcs.cli.control`): `fleetplan replan PATH ...` changes goals or drops
vehicles in flight. The flight and the mock vehicles run on their own thread
(`gcs.flight.host.vehicle_loop`), driven through a `gcs.service.replan_handle.ReplanHandle` (a
`FlightHandle` that also replans) as the REST service drives them; the signals
(`gcs.cli.fly_signals`) and the live status (`gcs.cli.fly_status`) are handled on the main
thread's loop.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from gcs.autopilot import px4
from gcs.cli import fly_options, mock_timings
from gcs.sim.realism import REALISMS

if TYPE_CHECKING:
    import asyncio
    from collections.abc import Callable

    from gcs.documents import FlightEvent
    from gcs.flight.host.vehicle_loop import VehicleLoop
    from gcs.service.replan_handle import ReplanHandle
    from gcs.sim import MockFleet
    from planner import Plan

__all__ = ["configure", "run", "tolerance_text"]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("plan", help="Plan JSON (from `fleetplan plan`)")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--fleet", help="fleet file (JSON): connections, system ids, homes")
    source.add_argument("--mock", action="store_true",
                        help="start mock vehicles in this run, homes under the plan's starts")
    parser.add_argument("--record", help="write the flight record (JSON) here: the record so "
                        "far (\"partial\": true) about once a second, the whole one at the end")
    fly_options.add_flags(parser)
    parser.add_argument("--base-port", type=int, default=None,
                        help=f"--mock: vehicle i sends to this port + i (default "
                             f"{px4.OFFBOARD_GCS_BASE_PORT}, PX4 SITL's; when those ports are "
                             f"taken and neither port flag is given, free ones are chosen)")
    parser.add_argument("--listen-base-port", type=int, default=None,
                        help=f"--mock: vehicle i listens on this port + i (default "
                             f"{px4.OFFBOARD_VEHICLE_BASE_PORT}, as --base-port; a fleet of N > "
                             f"{px4.OFFBOARD_VEHICLE_BASE_PORT - px4.OFFBOARD_GCS_BASE_PORT}: "
                             f"{px4.OFFBOARD_GCS_BASE_PORT} + N, past its GCS ports)")
    parser.add_argument("--mock-settle", type=float, default=None,
                        help="--mock: arming rejected this long after start (s, default 5, "
                             "3.5 with --mock-realism px4)")
    mock_timings.add_flags(parser, "mock-")
    parser.add_argument("--mock-gcs-port", type=int, default=None,
                        help="--mock: also give every vehicle a GCS link sending to this port, "
                             "like PX4's, so QGroundControl or MAVProxy can watch the flight "
                             "(they listen on 14550; default: none)")
    parser.add_argument("--mock-realism", choices=REALISMS, default="ideal",
                        help="--mock: ideal vehicles (default) or px4: PX4 SITL's estimate noise, "
                             "lag, timings and telemetry (see fleetplan mock --realism)")
    parser.add_argument("--mock-position-error", type=float, default=None,
                        help="--mock: the fleet's position_error (m) for the margin check and "
                             "the goal tolerance, as a fleet file states it (e.g. 0.25 with "
                             "--mock-realism px4)")
    parser.add_argument("--control", metavar="PATH",
                        help="take commands on a unix socket at PATH while flying (mode 0600, "
                             "removed at the end): `fleetplan replan PATH ...` changes goals or "
                             "drops vehicles in flight")
    parser.add_argument("--quiet", "-q", action="store_true", help="no live progress")


def run(args: argparse.Namespace) -> int:
    """Fly the plan of `args` and return the exit status (0: the flight completed)."""
    import asyncio
    import sys

    from gcs.cli.plan_file import read_plan
    from gcs.flight.run.ground import ground_refusal
    try:
        plan = read_plan(args.plan, "fly")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if (on_ground := ground_refusal(plan)) is not None:
        print(f"error: {on_ground}", file=sys.stderr)
        return 2
    if (timings := _mock_flags(args, len(plan.scenario.ids))) is None:
        return 2
    if args.mock:
        args.base_port, args.listen_base_port = mock_ports(
            args.base_port, args.listen_base_port, len(plan.scenario.ids))
    return asyncio.run(_main(args, plan, timings))


def _mock_flags(args: argparse.Namespace, count: int) -> dict[str, float] | None:
    """The mock vehicles' timings from the --mock-* flags, once those flags (--mock-gcs-port
    and the port blocks of `count` vehicles too) are checked; None once what is wrong is
    printed (before anything starts)."""
    import sys

    from gcs.cli.hints import block_error, port_error
    from gcs.sim.config import timing_error
    try:
        timings = mock_timings.chosen(args, "mock-")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return None
    for bad_port in (port_error("--mock-gcs-port", args.mock_gcs_port),
                     block_error("--base-port", args.base_port, count),
                     block_error("--listen-base-port", args.listen_base_port, count)):
        if bad_port is not None:
            print(f"error: {bad_port}", file=sys.stderr)
            return None
    if args.mock_settle is not None:
        if (reason := timing_error("settle_time", args.mock_settle)) is not None:
            print(f"error: --mock-settle {reason}", file=sys.stderr)
            return None
        timings["settle_time"] = args.mock_settle
    return timings


async def _main(args: argparse.Namespace, plan: Plan, timings: dict[str, float]) -> int:
    """The flight with its vehicles (and the mocks) on a loop of their own, apart from this
    one, which handles the signals and the printing."""
    import asyncio

    from gcs.flight.host.vehicle_loop import VehicleLoop
    vehicles = VehicleLoop()
    vehicles.start()
    try:
        return await _fly(args, plan, timings, vehicles)
    finally:
        await asyncio.to_thread(vehicles.stop)


async def _fly(args: argparse.Namespace, plan: Plan, timings: dict[str, float],
               vehicles: VehicleLoop) -> int:
    """Connect, fly and report the flight on `vehicles`; the exit status."""
    import asyncio
    import contextlib
    import sys
    from pathlib import Path

    from gcs.cli.control import ControlServer
    from gcs.cli.fly_signals import FlightSignals
    from gcs.cli.fly_status import progress
    from gcs.cli.hints import live_warning
    from gcs.cli.record_file import RecordFile
    from gcs.flight.timeline.realtime import settle_heap
    ports = ("--base-port (the GCS side) and --listen-base-port (the mock vehicles)"
             if args.mock else "the connection URLs in the fleet file")
    events: asyncio.Queue[FlightEvent | None] = asyncio.Queue()

    def on_event(event: FlightEvent) -> None:
        """Warnings to stderr at once (even with --quiet), every event to the printer."""
        warning = live_warning(event, ports)
        if warning is not None:
            print(warning, file=sys.stderr, flush=True)
        events.put_nowait(event)

    if (connected := await _connect(args, plan, timings, vehicles, on_event, ports)) is None:
        return 2
    handle, mock = connected
    control = None
    if args.control:
        control = ControlServer(args.control, handle, len(plan.scenario.ids))
        try:
            await control.start()
        except OSError as exc:
            if mock is not None:
                await vehicles.call(mock.stop)
            print(f"error: --control: {exc}", file=sys.stderr)
            return 2
        print(f"control socket: {args.control} (fleetplan replan {args.control} ...)",
              flush=True)
    # this process's collections then skip the libraries (gcs.flight.timeline.realtime)
    settle_heap()
    task = handle.start()
    signals = FlightSignals(handle, task)
    printer = None if args.quiet else asyncio.create_task(progress(handle, events))
    record_file = RecordFile(Path(args.record), handle) if args.record else None
    if record_file is not None:
        record_file.start()  # as the flight goes: a killed station leaves it readable
    try:
        record, status = await _flown(task, handle)
    finally:
        if record_file is not None:
            await record_file.close()
        if control is not None:
            await control.close()
        signals.remove()
        if printer is not None:
            events.put_nowait(None)
            printer.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await printer
        if mock is not None and vehicles.alive:
            await vehicles.call(mock.stop)
    if record is not None:
        _print_summary(record)
    _write_record(args, record)
    return status


async def _connect(args: argparse.Namespace, plan: Plan, timings: dict[str, float],
                   vehicles: VehicleLoop, on_event: Callable[[FlightEvent], None], ports: str
                   ) -> tuple[ReplanHandle, MockFleet | None] | None:
    """The flight's handle, connected to the fleet file's vehicles or to mock ones started
    here, with the option flags over the fleet's options; None once what failed is printed
    (the mocks stopped)."""
    import sys

    from gcs.cli.hints import port_in_use_hint
    from gcs.errors import FleetFileError, GcsError
    from gcs.fleet.fleetfile import FleetSpec, load_fleet
    from gcs.service.replan_handle import ReplanHandle
    from gcs.sim import MockConfig, MockFleet, homes_under
    mock = None
    try:
        if args.mock:
            homes = homes_under(plan.scenario.starts)
            mock = MockFleet(homes=homes, gcs_base_port=args.base_port,
                             listen_base_port=args.listen_base_port,
                             config=MockConfig.preset(args.mock_realism, **timings),
                             gcs_link_port=args.mock_gcs_port)
            await vehicles.call(mock.start)
            fleet_dict = mock.fleet_dict(plan.scenario.ids)
            if args.mock_position_error is not None:
                fleet_dict["position_error"] = args.mock_position_error
            fleet = FleetSpec.from_dict(fleet_dict)
        else:
            fleet = load_fleet(args.fleet)
        options = fleet.options.replace(where="option", **fly_options.chosen(args))
        handle = await ReplanHandle.create(vehicles, plan, fleet, options, on_event=on_event)
    except (GcsError, OSError) as exc:
        if mock is not None:
            await vehicles.call(mock.stop)
        where = f"{exc.field}: " if isinstance(exc, FleetFileError) else ""
        print(f"error: {where}{exc.reason if isinstance(exc, FleetFileError) else exc}"
              f"{port_in_use_hint(exc, ports)}", file=sys.stderr)
        return None
    return handle, mock


async def _flown(task: asyncio.Future[dict[str, Any]], handle: ReplanHandle
                 ) -> tuple[dict[str, Any] | None, int]:
    """The flight record once the flight ends, and the exit status: 0 completed, 1 not (or
    the flight failed), 130 when a second Ctrl-C quit without waiting."""
    import asyncio
    import sys

    from gcs.errors import GcsError
    try:
        record = await task
        return record, 0 if record["summary"]["completed"] else 1
    except asyncio.CancelledError:
        print("interrupted again: quitting without waiting", file=sys.stderr)
        return handle.record, 130
    except GcsError as exc:
        print(f"flight failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return handle.record, 1


def _write_record(args: argparse.Namespace, record: dict[str, Any] | None) -> None:
    """The whole record to --record's file, when asked for and there is one."""
    from pathlib import Path

    from gcs.cli.record_file import write_json
    if args.record and record is not None:
        write_json(Path(args.record), record)
        print(f"flight record written to {args.record}")


def tolerance_text(summary: dict[str, Any]) -> str:
    """The goal tolerance the flight applied: each vehicle's (`goal_tolerances`: the fleet's
    `goal_tolerance`, or larger from the position error or the GPS accuracy a vehicle reports,
    1.8 m on PX4 SIH), not only the fleet-wide base."""
    applied = [t for t in (summary.get("goal_tolerances") or {}).values() if t is not None]
    if not applied:
        base = summary.get("goal_tolerance")
        return "tolerance n/a" if base is None else f"tolerance {base:.3f} m"
    lo, hi = min(applied), max(applied)
    return f"tolerance {hi:.3f} m" if lo == hi else f"tolerances {lo:.3f}-{hi:.3f} m"


def _print_summary(record: dict[str, Any]) -> None:
    s = record["summary"]

    def fmt(value: float | None, unit: str = "") -> str:
        return "n/a" if value is None else f"{value:.3f}{unit}"

    print("summary:")
    print(f"  completed               {s['completed']}")
    for reason in s.get("why", []):
        print(f"    {reason}")
    print(f"  goal_error_max          {fmt(s['goal_error_max'], ' m')}"
          f" ({tolerance_text(s)})")
    print(f"  tracking_error_max      {fmt(s['tracking_error_max'], ' m')}")
    print(f"  min_separation_measured {fmt(s['min_separation_measured'], ' m')}"
          f" (planned {fmt(s['min_separation_planned'], ' m')}, must keep "
          f"{fmt(s.get('min_separation_required'), ' m')})")
    print(f"  setpoint_rate_hz        {fmt(s['setpoint_rate_hz'])}")
    print(f"  jitter_p99_ms           {fmt(s['jitter_p99_ms'])}")
    if s["faults"]:
        print(f"  faults                  {s['faults']}")
    if record.get("error"):
        print(f"  error                   {record['error']['type']}: "
              f"{record['error']['message']}")


def mock_ports(base: int | None, listen: int | None, count: int) -> tuple[int, int]:
    """The mock fleet's (GCS-side base, vehicle listen base): the flags given; else PX4
    SITL's ports when all `count` of each are free; else a free block elsewhere, said on
    stdout (the usual ports are held by `make run`, another fly or a mock). A fleet larger
    than PX4 SITL's layout holds listens past its own GCS ports (`gcs.sim.ports`)."""
    from gcs.sim import ports

    usual = px4.OFFBOARD_GCS_BASE_PORT
    usual_listen = usual + ports.listen_offset(count)
    if base is not None or listen is not None:
        return (usual if base is None else base, usual_listen if listen is None else listen)
    offsets = ports.mock_port_offsets(count)
    if ports.block_free(usual, offsets):
        return usual, usual_listen
    chosen = ports.free_udp_base(offsets)
    print(f"ports {usual}.. and {usual_listen}.. are taken (by `make run`, "
          f"fleetplan serve, another fly or a mock?): the mock fleet flies on {chosen}.. and "
          f"{chosen + ports.listen_offset(count)}.. instead", flush=True)
    return chosen, chosen + ports.listen_offset(count)
