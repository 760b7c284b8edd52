"""`fleetplan serve` whose mock vehicles carry `FAST_MOCK` (land at 1 m/s, disarm 0.5 s after
touching down, status at 5 Hz), as `quick_service_mocks` gives an in-process service: what
`ServiceProcess(..., quick_mocks=True)` runs (`python -m tests.api.quick_serve serve ...`)."""

from __future__ import annotations

import sys

import gcs.service.fleet
from gcs.cli.main import main
from tests.api.support import QuickMockConfig

gcs.service.fleet.MockConfig = QuickMockConfig  # type: ignore[misc]

if __name__ == "__main__":
    sys.exit(main())
