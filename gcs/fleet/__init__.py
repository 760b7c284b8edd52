"""The fleet outside a flight: its fleet file (how to reach each vehicle, its home, the flight
options), the fleet commands (hold, land, rtl, disarm, terminate) and key provisioning."""
