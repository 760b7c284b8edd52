"""What the GCS exchanges with each vehicle over MAVLink: endpoints, signing, the per-vehicle
link with its telemetry, the fleet's hub, the setpoints it sends and the station's own stalls."""
