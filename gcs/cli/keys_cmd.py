"""`fleetplan keys new FILE`: make a MAVLink 2 signing key file (32 random bytes, mode 0600);
`fleetplan keys provision --fleet FLEET.json`: put the fleet file's keys on its vehicles.

Name a key in the fleet file (``"signing_key": "FILE"``, fleet-wide or per vehicle), then
provision it over a link you trust while the vehicles are disarmed (`gcs.fleet.provision`;
docs: Security, Provisioning). The key itself is never printed; an existing file is never
overwritten.
"""

from __future__ import annotations

import argparse

__all__ = ["configure", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="keys_command", metavar="ACTION", required=True)
    new = sub.add_parser("new", help="create a new random signing key file (mode 0600)",
                         description="create a new random signing key file (mode 0600)")
    new.add_argument("file", help="the key file to create (must not exist)")
    what = ("send the fleet file's signing keys to its disarmed vehicles (SETUP_SIGNING) and "
            "check that their traffic is then signed with them")
    provision = sub.add_parser("provision", help=what, description=what)
    provision.add_argument("--fleet", required=True, metavar="FLEET.json",
                           help="the fleet file: links and each vehicle's signing_key")
    provision.add_argument("--vehicle", action="append", default=[], metavar="ID",
                           help="only this vehicle (repeatable; default: every vehicle with "
                                "a signing_key)")
    provision.add_argument("--old-key", metavar="FILE",
                           help="the key the vehicles have now, to change it (the change is "
                                "signed with it, as PX4 requires)")
    provision.add_argument("--timeout", type=float, default=5.0, metavar="S",
                           help="seconds to wait for each vehicle at each step (default 5)")


def run(args: argparse.Namespace) -> int:
    if args.keys_command == "provision":
        return _provision(args)
    import sys

    from gcs.wire import KeyFileError, new_key_file

    try:
        key = new_key_file(args.file)
    except KeyFileError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote signing key {key.path} (32 bytes, mode 0600): name it in the fleet file as "
          f'"signing_key" and provision it on the vehicles over a trusted link')
    return 0


def _provision(args: argparse.Namespace) -> int:
    """Exit 0 when every vehicle's traffic is signed with its key, 1 when one failed, 2 on
    bad arguments; one line per vehicle, naming key files, never keys."""
    import asyncio
    import math
    import sys

    from gcs.errors import FleetFileError, GcsError
    from gcs.fleet.fleetfile import load_fleet
    from gcs.fleet.provision import provision_fleet
    from gcs.wire import KeyFileError, load_key

    if not (math.isfinite(args.timeout) and 0 < args.timeout <= 60):
        print(f"error: --timeout: must be in (0, 60] s, got {args.timeout:g}", file=sys.stderr)
        return 2
    try:
        fleet = load_fleet(args.fleet)
        old = load_key(args.old_key) if args.old_key else None
    except FleetFileError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyFileError as exc:
        print(f"error: --old-key: {exc}", file=sys.stderr)
        return 2
    if not any(v.signing_key is not None for v in fleet.vehicles):
        print(f"error: {args.fleet}: no vehicle has a signing_key (make one with fleetplan "
              "keys new FILE and name it in the fleet file)", file=sys.stderr)
        return 2
    try:
        outcomes = asyncio.run(provision_fleet(fleet, args.vehicle, old, args.timeout))
    except ValueError as exc:
        print(f"error: --vehicle: {exc}", file=sys.stderr)
        return 2
    except GcsError as exc:  # a link that cannot be opened (a port in use, ...)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for outcome in outcomes:
        print(outcome.line(), file=sys.stdout if outcome.ok else sys.stderr)
    return 0 if all(o.ok for o in outcomes) else 1
