"""The REST API and browser page of fleetplan (FastAPI). Build it with `create_app`."""

from __future__ import annotations

from gcs.api.app import create_app

__all__ = ["create_app"]
