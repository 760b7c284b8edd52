"""The PX4 procedure on a vehicle's link: connect, modes, arming, landing, and the geofence
upload; shared by a flight and by fleet commands outside one."""
