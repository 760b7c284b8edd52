"""MAVLink facts shared by the GCS (`gcs.flight`) and the PX4-like mock (`gcs.sim`).

The wire format is pymavlink's MAVLink 2 `common` dialect; this module is the one place that
selects it. Everything here is a constant or a pure function, so the mock can share it without
sharing our link code.
"""

from __future__ import annotations

import os

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink

__all__ = ["mavlink"]
