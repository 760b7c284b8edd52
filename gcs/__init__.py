"""fleetplan ground-control side: MAVLink links, PX4 offboard flight, mock autopilot, API, CLI."""
