"""Flying a plan on a fleet of PX4 or ArduPilot vehicles, in sub-packages from the wire up,
each importing only those before it (`tests/test_layout.py`, `FLIGHT_LAYERS`).

- `link`: one vehicle's MAVLink link and the links of a fleet (endpoints, signing, telemetry,
  the setpoints the link sends, the ground station's own stalls);
- `procedure`: the procedure on a link, asking the vehicle's autopilot (connect, modes,
  arming, landing, parameters, the link-loss failsafe, the geofence), and the flight context
  its steps take;
- `timeline`: the flight's time (the setpoint stream that ticks for the whole fleet, the
  flight clock, the plans flown in flight time);
- `replan`: replanning a flying fleet, and the motions predicted off its plans;
- `safety`: the margin a fleet needs, health, fault detection, the fault policy, landing;
- `run`: one flight (the executor and its parts: boarding, arrival, pausing, fault routing,
  securing, the record and the live snapshot);
- `host`: the thread and the process that run flights apart from their caller.
"""
