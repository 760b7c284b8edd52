"""Plans written in other tools' formats (a Skybrush compiled show: `gcs.export.skyc`; the
geofence as a QGroundControl `.plan` file: `gcs.export.qgc_plan`).

Pure functions of a `planner.Plan` to bytes: no vehicles, no service, no web; the CLI
(`fleetplan export`) and the REST API (`GET /api/missions/{id}/show.skyc`) call them.
"""
