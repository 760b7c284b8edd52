"""Flying a plan on a fleet of PX4 or ArduPilot vehicles, in sub-packages from the wire up.

- `link`: one vehicle's MAVLink link and the links of a fleet (endpoints, signing, telemetry,
  the setpoints the link sends, the ground station's own stalls);
- `procedure`: the procedure on a link, asking the vehicle's autopilot (connect, modes,
  arming, landing, parameters, the link-loss failsafe, the geofence);
- `safety`: the margin a fleet needs, health, fault detection, the fault policy, landing;
- `replan`: replanning a flying fleet;
- `run`: one flight on one clock (the executor, boarding, the stream, the flight clock, the
  record and the live snapshot);
- `host`: the thread and the process that run flights apart from their caller.
"""
