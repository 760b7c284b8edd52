"""How a mock fleet behaves (`MockConfig`, its presets `REALISMS`) and what faults are injected
into one vehicle (`MockFaults`): plain settings, read by every other module of `gcs.sim`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from gcs.autopilot import px4
from gcs.sim.model import EstimateNoise, ModelLimits
from gcs.sim.realism import REALISMS, Realism

__all__ = ["AUTOPILOTS", "REALISMS", "TIMING_BOUNDS", "MockConfig", "MockFaults", "Realism",
           "timing_error"]


#: The `MockConfig` timings a user may change (`fleetplan fly --mock` and `fleetplan mock`
#: flags, the service's mock_* settings): field -> (lowest, highest, unit). A status rate must
#: be above its lowest; the others may equal it.
TIMING_BOUNDS: dict[str, tuple[float, float, str]] = {
    "settle_time": (0.0, 60.0, "s"),
    "status_rate": (0.0, 50.0, "Hz"),
    "land_speed": (0.2, 3.0, "m/s"),
    "disarm_after_land": (0.1, 20.0, "s"),
}


#: The autopilots whose rules the mock follows (`MockConfig.autopilot`).
AUTOPILOTS = ("px4", "ardupilot")


def timing_error(name: str, value: float) -> str | None:
    """Why `value` cannot be the timing `name` (`TIMING_BOUNDS`), or None when it can."""
    low, high, unit = TIMING_BOUNDS[name]
    above = value > low if name == "status_rate" else value >= low
    if math.isfinite(value) and above and value <= high:
        return None
    bracket = "(" if name == "status_rate" else "["
    return f"must be within {bracket}{low:g}, {high:g}] {unit}, got {value}"


@dataclass
class MockConfig:
    """Behaviour shared by every vehicle of a `MockFleet` (PX4 defaults unless said)."""

    autopilot: str = "px4"
    """Whose rules it follows: ``px4``, or ``ardupilot`` (ArduCopter 4.7: `gcs.sim.arducopter`;
    settle_time is then how long arming fails its pre-arm checks)."""
    settle_time: float = 5.0
    """Arming is TEMPORARILY_REJECTED this long after start (PX4 SITL: about 4-5 s)."""
    offboard_loss_timeout: float = px4.COM_OF_LOSS_T_S
    """COM_OF_LOSS_T (s)."""
    failsafe_action_delay: float = px4.COM_FAIL_ACT_T_S
    """COM_FAIL_ACT_T (s): the offboard-loss failsafe holds in Position this long, then takes
    `offboard_loss_action`."""
    offboard_loss_action: int = 0
    """COM_OBL_RC_ACT (`gcs.autopilot.px4.OBL_ACTIONS`): 0-2 and 4 land (no RC), 3 RTL, 5 Hold,
    6 terminate, 7 disarm."""
    disarm_after_land: float = px4.COM_DISARM_LAND_S
    """COM_DISARM_LAND (s)."""
    disarm_preflight: float = px4.COM_DISARM_PRFLT_S
    """COM_DISARM_PRFLT (s)."""
    land_speed: float = 0.7
    """MPC_LAND_SPEED (m/s)."""
    takeoff_altitude: float = 2.5
    """MIS_TAKEOFF_ALT: AUTO.TAKEOFF's lowest height above home (m)."""
    rtl_return_altitude: float = 60.0
    """RTL_RETURN_ALT: AUTO.RTL climbs to this height above home before returning (m)."""
    geofence_action: int = 2
    """GF_ACTION on a geofence breach: 0 none, 1 warning, 2 Hold, 3 RTL, 4 terminate, 5 land."""
    manual_control_timeout: float = 0.5
    """COM_RC_LOSS_T: manual control input older than this is lost; Position mode is then
    refused (s)."""
    physics_rate: float = 200.0
    """Integration rate of the vehicle model (Hz, >= 100)."""
    position_rate: float = 30.0
    """LOCAL_POSITION_NED rate (Hz), as PX4's onboard link streams it."""
    attitude_rate: float = 20.0
    global_position_rate: float = 5.0
    status_rate: float = 1.0
    """HEARTBEAT, SYS_STATUS, EXTENDED_SYS_STATE rate (Hz)."""
    battery_drain: float = 0.05
    """Battery drain while armed (% per second; a 20-minute battery)."""
    gps_rate: float = 5.0
    """GPS_RAW_INT rate (Hz)."""
    telemetry_profile: str = "minimal"
    """What the offboard link sends (`gcs.sim.telemetry`): ``minimal`` (the rates above, about
    65 messages/s) or ``px4`` (PX4's offboard-link set and rates, about 410 messages/s)."""
    record_setpoints: bool = False
    """Keep every accepted setpoint in `MockVehicle.received` (for tests)."""
    limits: ModelLimits = field(default_factory=ModelLimits)
    realism: str = "ideal"
    """Which preset this is (`REALISMS`); set by `preset`, informational."""
    seed: int = 0
    """Seed of every random process of the fleet (estimate noise, injected loss)."""
    estimate_noise: EstimateNoise | None = None
    """The position estimate's error process (None: exact, as in the ideal mode)."""
    boot_time: float = 0.0
    """Nothing is sent or answered this long after start; the first HEARTBEAT then goes at
    the next 1 s tick (2 s for 1.5 s; PX4 SITL: 1.7-2.7 s)."""
    duplicate_ack_delay: float = 0.0
    """DO_SET_MODE and REQUEST_MESSAGE are ACKed twice; the second ACK goes this much later (s)."""

    @classmethod
    def preset(cls, realism: str = "ideal", **overrides: Any) -> MockConfig:
        """The named preset (`REALISMS`), with `overrides` applied (unknown names: TypeError)."""
        if realism not in REALISMS:
            raise ValueError(f"realism must be one of {', '.join(REALISMS)}, got {realism!r}")
        config = cls.px4_like() if realism == "px4" else cls()
        for key, value in overrides.items():
            if not hasattr(config, key):
                raise TypeError(f"unknown mock setting {key!r}")
            setattr(config, key, value)
        return config

    @classmethod
    def px4_like(cls) -> MockConfig:
        """PX4 v1.16 SIH SITL as measured (README "Mock realism" has the figures): a wandering
        position estimate (GPS-like altitude noise), the attitude loop's lag, arming refused
        for 3.5 s after boot, deaf and silent for 1.5 s (first HEARTBEAT at 2 s), PX4's
        offboard message set."""
        return cls(realism="px4", settle_time=3.5, boot_time=1.5,
                   estimate_noise=EstimateNoise(), duplicate_ack_delay=0.005,
                   telemetry_profile="px4",
                   limits=ModelLimits(thrust_time_constant=0.15))


@dataclass
class MockFaults:
    """Faults injected into one mock vehicle; change them at any time."""

    loss: float = 0.0
    """Fraction of packets dropped, each direction independently (0..1)."""
    heartbeats: bool = True
    """False: stop sending HEARTBEAT (everything else continues)."""
    silent: bool = False
    """True: send nothing at all (a dead radio or a crashed companion link)."""
    delay: float = 0.0
    """Seconds added to every packet, both directions."""
    refuse_arming: bool = False
    """Arming answered DENIED."""
    nan_position: bool = False
    """LOCAL_POSITION_NED reports NaN position and velocity (a broken estimator)."""
    battery: float | None = None
    """Battery remaining (%) reported instead of the simulated one."""
    unhealthy: int = 0
    """SYS_STATUS sensor bits reported present and enabled but not healthy."""
    gps_fix: int | None = None
    """GPS_RAW_INT fix_type reported instead of 3 (3D fix)."""
    params_silent: bool = False
    """No answer to any parameter message (PARAM_REQUEST_READ, PARAM_SET, ...)."""
    params_kept: frozenset[str] = frozenset()
    """PARAM_SET of these parameters is answered with the unchanged value (a vehicle that
    will not change them)."""
    offset_ned: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Added to every position setpoint the vehicle then takes (LOCAL_NED, m): it holds a
    constant error from the plan (an uncompensated wind, a biased controller) and reports
    where it really is."""
