"""One flight on one shared clock: the executor, each vehicle's boarding, the setpoint stream,
the flight clock, the plans flown, the flight record and the live snapshot."""
