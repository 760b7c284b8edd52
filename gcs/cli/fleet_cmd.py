"""`fleetplan fleet COMMAND --fleet FLEET.json [--vehicle ID]`: command vehicles between flights.

COMMAND is hold, land, rtl, disarm or terminate (`gcs.fleet.commands`). Opens the fleet
file's connections, waits for the chosen vehicles' HEARTBEAT, sends the command to all of them
at once and prints what each confirmed. ``land`` and ``rtl`` then wait (``--wait``, default
on) until every vehicle has landed and disarmed. ``disarm`` in the air needs ``--force``,
``terminate`` needs ``--confirm``. Exit status 0 only when every vehicle did it.

``land --plan PLAN.json`` lands a fleet left hovering (a lost station's Hold failsafe, where
the plan stacks two vehicles closer than R horizontally) by a verified landing plan from
where each vehicle is, instead of straight down (`gcs.cli.land_plan`).
"""

from __future__ import annotations

import argparse

from gcs.phases import FLEET_COMMANDS

__all__ = ["configure", "run"]

#: Waiting for the chosen vehicles' first HEARTBEAT (s).
CONNECT_TIMEOUT_S = 10.0


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("command", choices=FLEET_COMMANDS,
                        help="hold, land, rtl (return to launch), disarm (refused in the air "
                             "unless --force), terminate (motors off; needs --confirm)")
    parser.add_argument("--fleet", required=True, help="fleet file (JSON): connections")
    parser.add_argument("--vehicle", action="append", metavar="ID",
                        help="only this vehicle (repeat for more; default: the whole fleet)")
    parser.add_argument("--force", action="store_true",
                        help="disarm: even in the air (the vehicle falls)")
    parser.add_argument("--confirm", action="store_true",
                        help="terminate: yes, stop the motors in flight")
    parser.add_argument("--no-wait", dest="wait", action="store_false",
                        help="land/rtl: do not wait for the vehicles to land and disarm")
    parser.add_argument("--plan", metavar="PLAN.json",
                        help="land: by a landing plan under this plan's workspace, obstacles "
                             "and R, from where each vehicle hovers (vehicles stacked closer "
                             "than R land side by side), instead of straight down")
    parser.add_argument("--timeout", type=float, default=120.0,
                        help="land/rtl: wait at most this long for the disarm (s, default 120)")


def run(args: argparse.Namespace) -> int:
    import asyncio
    import sys
    import time

    from gcs.errors import FleetFileError, GcsError, RequestError
    from gcs.fleet.commands import fleet_command
    from gcs.fleet.fleetfile import load_fleet
    from gcs.flight.link.hub import LinkHub
    from gcs.flight.link.link import DECODED_IDS

    try:
        fleet = load_fleet(args.fleet)
    except FleetFileError as exc:
        print(f"error: {exc.field}: {exc.reason}", file=sys.stderr)
        return 2
    known = [v.id for v in fleet.vehicles]
    chosen = args.vehicle or known
    unknown = [vid for vid in chosen if vid not in known]
    if unknown:
        print(f"error: --vehicle: no vehicle {', '.join(unknown)} in {args.fleet} "
              f"(it has {', '.join(known)})", file=sys.stderr)
        return 2
    if not (args.timeout > 0):
        print("error: --timeout must be positive", file=sys.stderr)
        return 2
    if args.plan is not None:
        if args.command != "land":
            print(f"error: --plan: only for land, not {args.command}", file=sys.stderr)
            return 2
        from gcs.cli import land_plan
        return land_plan.run(args, fleet, chosen, CONNECT_TIMEOUT_S)

    async def main() -> int:
        async with LinkHub(decode_ids=DECODED_IDS) as hub:
            links = {}
            for spec in fleet.vehicles:
                if spec.id in chosen:
                    links[spec.id] = await hub.add(spec.id, spec.connection, spec.system_id,
                                                   spec.component_id)
            await asyncio.gather(*(link.wait_for(lambda t: t.heartbeat_time is not None,
                                                 CONNECT_TIMEOUT_S) for link in links.values()))
            try:
                outcomes = await fleet_command(links, args.command, force=args.force,
                                               confirm=args.confirm)
            except RequestError as exc:
                print(f"refused: {exc.field}: {exc.reason}", file=sys.stderr)
                return 2
            for o in outcomes:
                state = "armed" if o.armed else "disarmed" if o.armed is not None else "?"
                print(f"{o.vehicle}: {'done' if o.done else 'NOT DONE'}: {o.detail} "
                      f"[{o.mode or '?'}, {state}]", flush=True)
            if not all(o.done for o in outcomes):
                return 1
            if args.command in ("land", "rtl") and args.wait:
                deadline = time.monotonic() + args.timeout
                pending = dict(links)
                while pending and time.monotonic() < deadline:
                    for vid, link in list(pending.items()):
                        if not link.telemetry.armed and link.heartbeat_age() < 3.0:
                            print(f"{vid}: landed and disarmed", flush=True)
                            del pending[vid]
                    await asyncio.sleep(0.2)
                if pending:
                    print(f"still armed after {args.timeout:g} s: {', '.join(pending)}",
                          file=sys.stderr)
                    return 1
            return 0

    try:
        return asyncio.run(main())
    except GcsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
