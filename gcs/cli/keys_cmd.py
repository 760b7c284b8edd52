"""`fleetplan keys new FILE`: make a MAVLink 2 signing key file (32 random bytes, mode 0600).

Name it in the fleet file (``"signing_key": "FILE"``, fleet-wide or per vehicle) and provision
the same key on the vehicles over a trusted link (README, "Security: signed links and pinned
peers"). The key itself is never printed; an existing file is never overwritten.
"""

from __future__ import annotations

import argparse

__all__ = ["configure", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="keys_command", metavar="ACTION", required=True)
    new = sub.add_parser("new", help="create a new random signing key file (mode 0600)",
                         description="create a new random signing key file (mode 0600)")
    new.add_argument("file", help="the key file to create (must not exist)")


def run(args: argparse.Namespace) -> int:
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
