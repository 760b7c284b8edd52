"""The mock's PX4 parameter set, as data: name, type, PX4 default and documented range.

A realistic subset of PX4 v1.16's parameters for a multicopter in SITL (the commander,
navigator, geofence, position controller, MAVLink, estimator and sensor groups ground stations
read at connect), with PX4's types (REAL32 or INT32) and defaults from PX4's parameter
metadata. Ranges are PX4's documented min/max (metadata for ground stations: PX4 itself stores
any value). Which of them change the mock's behaviour is `gcs.sim.params.MODELLED`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from gcs.autopilot import px4

__all__ = ["PX4_PARAMS", "ParamDef"]

Kind = Literal["f", "i"]
"""REAL32 ("f") or INT32 ("i"), the two types PX4's parameters have."""


@dataclass(frozen=True)
class ParamDef:
    """One PX4 parameter: name (at most 16 characters), type, default and range."""

    name: str
    kind: Kind
    default: float
    low: float
    high: float


_F: Kind = "f"
_I: Kind = "i"
_BIG = 1e9

#: (name, type, default, min, max): PX4's multicopter defaults (v1.16 metadata).
_TABLE: tuple[tuple[str, Kind, float, float, float], ...] = (
    # commander
    ("COM_ARM_WO_GPS", _I, 1, 0, 2),
    ("COM_ARM_CHK_ESCS", _I, 0, 0, 1),
    ("COM_ARM_MAG_ANG", _I, 60, -1, 180),
    ("COM_ARM_SDCARD", _I, 1, 0, 2),
    ("COM_CPU_MAX", _F, 95.0, -1.0, 100.0),
    ("COM_DISARM_LAND", _F, px4.COM_DISARM_LAND_S, -1.0, 20.0),
    ("COM_DISARM_PRFLT", _F, px4.COM_DISARM_PRFLT_S, -1.0, 20.0),
    ("COM_DL_LOSS_T", _I, 10, 5, 300),
    ("COM_FAIL_ACT_T", _F, px4.COM_FAIL_ACT_T_S, 0.0, 25.0),
    ("COM_FLTMODE1", _I, -1, -1, 13),
    ("COM_FLTMODE2", _I, -1, -1, 13),
    ("COM_FLTMODE3", _I, -1, -1, 13),
    ("COM_FLTMODE4", _I, -1, -1, 13),
    ("COM_FLTMODE5", _I, -1, -1, 13),
    ("COM_FLTMODE6", _I, -1, -1, 13),
    ("COM_HOME_EN", _I, 1, 0, 1),
    ("COM_LOW_BAT_ACT", _I, 0, 0, 3),
    ("COM_OBL_RC_ACT", _I, 0, 0, 7),
    ("COM_OBS_AVOID", _I, 0, 0, 1),
    ("COM_OF_LOSS_T", _F, px4.COM_OF_LOSS_T_S, 0.0, 60.0),
    ("COM_POSCTL_NAVL", _I, 0, 0, 1),
    ("COM_POS_FS_DELAY", _I, 1, 1, 100),
    ("COM_PREARM_MODE", _I, 0, 0, 1),
    ("COM_RCL_EXCEPT", _I, 0, 0, 31),
    ("COM_RC_IN_MODE", _I, 3, 0, 4),
    ("COM_RC_LOSS_T", _F, 0.5, 0.0, 35.0),
    ("COM_SPOOLUP_TIME", _F, 1.0, 0.0, 30.0),
    ("COM_TAKEOFF_ACT", _I, 0, 0, 1),
    # navigator, mission, return
    ("MIS_DIST_1WP", _F, 900.0, -1.0, 10000.0),
    ("MIS_TAKEOFF_ALT", _F, 2.5, 0.0, 1000.0),
    ("MIS_TKO_LAND_REQ", _I, 0, 0, 5),
    ("MIS_YAW_TMT", _F, -1.0, -1.0, 20.0),
    ("MIS_YAW_ERR", _F, 12.0, 0.0, 90.0),
    ("NAV_ACC_RAD", _F, 2.0, 0.05, 200.0),
    ("NAV_DLL_ACT", _I, 0, 0, 6),
    ("NAV_FORCE_VT", _I, 1, 0, 1),
    ("NAV_LOITER_RAD", _F, 80.0, 25.0, 1000.0),
    ("NAV_MC_ALT_RAD", _F, 0.8, 0.05, 200.0),
    ("NAV_RCL_ACT", _I, 2, 0, 6),
    ("NAV_TRAFF_AVOID", _I, 1, 0, 4),
    ("RTL_CONE_ANG", _I, 45, 0, 90),
    ("RTL_DESCEND_ALT", _F, 30.0, 0.0, 1000.0),
    ("RTL_LAND_DELAY", _F, 0.0, -1.0, 300.0),
    ("RTL_MIN_DIST", _F, 10.0, 0.5, 100.0),
    ("RTL_RETURN_ALT", _F, 60.0, 0.0, 1000.0),
    ("RTL_TYPE", _I, 0, 0, 3),
    # geofence
    ("GF_ACTION", _I, 2, 0, 5),
    ("GF_ALTMODE", _I, 0, 0, 1),
    ("GF_COUNT", _I, -1, -1, 10),
    ("GF_MAX_HOR_DIST", _F, 0.0, 0.0, 10000.0),
    ("GF_MAX_VER_DIST", _F, 0.0, 0.0, 10000.0),
    ("GF_PREDICT", _I, 1, 0, 1),
    ("GF_SOURCE", _I, 0, 0, 1),
    # multicopter position control
    ("MPC_ACC_DOWN_MAX", _F, 3.0, 2.0, 15.0),
    ("MPC_ACC_HOR", _F, 3.0, 2.0, 15.0),
    ("MPC_ACC_HOR_MAX", _F, 5.0, 2.0, 15.0),
    ("MPC_ACC_UP_MAX", _F, 4.0, 2.0, 15.0),
    ("MPC_HOLD_MAX_XY", _F, 0.8, 0.0, 3.0),
    ("MPC_HOLD_MAX_Z", _F, 0.6, 0.0, 3.0),
    ("MPC_JERK_AUTO", _F, 4.0, 1.0, 80.0),
    ("MPC_JERK_MAX", _F, 8.0, 0.5, 500.0),
    ("MPC_LAND_ALT1", _F, 10.0, 0.0, 122.0),
    ("MPC_LAND_ALT2", _F, 5.0, 0.0, 122.0),
    ("MPC_LAND_CRWL", _F, 0.3, 0.1, _BIG),
    ("MPC_LAND_SPEED", _F, 0.7, 0.6, _BIG),
    ("MPC_MAN_TILT_MAX", _F, 35.0, 0.0, 90.0),
    ("MPC_POS_MODE", _I, 4, 0, 4),
    ("MPC_THR_HOVER", _F, 0.5, 0.1, 0.8),
    ("MPC_THR_MAX", _F, 1.0, 0.0, 1.0),
    ("MPC_THR_MIN", _F, 0.12, 0.05, 0.5),
    ("MPC_TILTMAX_AIR", _F, 45.0, 20.0, 89.0),
    ("MPC_TILTMAX_LND", _F, 12.0, 10.0, 89.0),
    ("MPC_TKO_RAMP_T", _F, 3.0, 0.1, 10.0),
    ("MPC_TKO_SPEED", _F, 1.5, 1.0, 5.0),
    ("MPC_VEL_MANUAL", _F, 10.0, 1.0, 20.0),
    ("MPC_XY_CRUISE", _F, 5.0, 3.0, 20.0),
    ("MPC_XY_P", _F, 0.95, 0.0, 2.0),
    ("MPC_XY_VEL_D_ACC", _F, 0.2, 0.1, 2.0),
    ("MPC_XY_VEL_I_ACC", _F, 0.4, 0.0, 60.0),
    ("MPC_XY_VEL_MAX", _F, 12.0, 0.0, 20.0),
    ("MPC_XY_VEL_P_ACC", _F, 1.8, 1.2, 5.0),
    ("MPC_YAWRAUTO_MAX", _F, 45.0, 0.0, 360.0),
    ("MPC_Z_P", _F, 1.0, 0.1, 1.5),
    ("MPC_Z_VEL_D_ACC", _F, 0.0, 0.0, 2.0),
    ("MPC_Z_VEL_I_ACC", _F, 2.0, 0.2, 3.0),
    ("MPC_Z_VEL_MAX_DN", _F, 1.5, 0.5, 4.0),
    ("MPC_Z_VEL_MAX_UP", _F, 3.0, 0.5, 8.0),
    ("MPC_Z_VEL_P_ACC", _F, 4.0, 2.0, 15.0),
    # multicopter attitude and rate control
    ("MC_PITCHRATE_MAX", _F, 220.0, 0.0, 1800.0),
    ("MC_PITCHRATE_P", _F, 0.15, 0.01, 0.6),
    ("MC_PITCH_P", _F, 6.5, 0.0, 12.0),
    ("MC_ROLLRATE_MAX", _F, 220.0, 0.0, 1800.0),
    ("MC_ROLLRATE_P", _F, 0.15, 0.01, 0.5),
    ("MC_ROLL_P", _F, 6.5, 0.0, 12.0),
    ("MC_YAWRATE_MAX", _F, 200.0, 0.0, 1800.0),
    ("MC_YAWRATE_P", _F, 0.2, 0.0, 0.6),
    ("MC_YAW_P", _F, 2.8, 0.0, 5.0),
    ("MC_AIRMODE", _I, 0, 0, 2),
    # land detector
    ("LNDMC_ALT_MAX", _F, -1.0, -1.0, 10000.0),
    ("LNDMC_XY_VEL_MAX", _F, 1.5, 0.0, 10.0),
    ("LNDMC_Z_VEL_MAX", _F, 0.5, 0.0, 10.0),
    # MAVLink
    ("MAV_0_BROADCAST", _I, 1, 0, 2),
    ("MAV_0_CONFIG", _I, 0, 0, 300),
    ("MAV_0_MODE", _I, 0, 0, 13),
    ("MAV_0_RATE", _I, 4000000, 0, _BIG),
    ("MAV_1_CONFIG", _I, 0, 0, 300),
    ("MAV_COMP_ID", _I, 1, 1, 250),
    ("MAV_FWDEXTSP", _I, 1, 0, 1),
    ("MAV_HASH_CHK_EN", _I, 1, 0, 1),
    ("MAV_HB_FORW_EN", _I, 1, 0, 1),
    ("MAV_PROTO_VER", _I, 0, 0, 2),
    ("MAV_RADIO_TOUT", _I, 5, 1, 250),
    ("MAV_SIK_RADIO_ID", _I, 0, -1, 240),
    ("MAV_SYS_ID", _I, 1, 1, 250),
    ("MAV_TYPE", _I, 2, 0, 23),
    # system
    ("SYS_AUTOCONFIG", _I, 0, 0, 2),
    ("SYS_AUTOSTART", _I, 10040, 0, 9999999),
    ("SYS_BL_UPDATE", _I, 0, 0, 1),
    ("SYS_CAL_ACCEL", _I, 0, 0, 1),
    ("SYS_CAL_BARO", _I, 0, 0, 1),
    ("SYS_CAL_GYRO", _I, 0, 0, 1),
    ("SYS_FAILURE_EN", _I, 0, 0, 1),
    ("SYS_HAS_BARO", _I, 1, 0, 1),
    ("SYS_HAS_GPS", _I, 1, 0, 1),
    ("SYS_HAS_MAG", _I, 1, 0, 4),
    ("SYS_HITL", _I, 0, -1, 2),
    ("SYS_MC_EST_GROUP", _I, 2, 1, 3),
    ("SYS_RESTART_TYPE", _I, 0, 0, 2),
    ("SYS_USE_IO", _I, 0, 0, 1),
    ("SYS_VEHICLE_RESP", _F, -0.4, -1.0, 1.0),
    # estimator
    ("EKF2_AID_MASK", _I, 1, 0, 511),
    ("EKF2_BARO_NOISE", _F, 3.5, 0.01, 15.0),
    ("EKF2_EN", _I, 1, 0, 1),
    ("EKF2_EV_CTRL", _I, 15, 0, 15),
    ("EKF2_GPS_CTRL", _I, 7, 0, 15),
    ("EKF2_GPS_P_NOISE", _F, 0.5, 0.01, 10.0),
    ("EKF2_GPS_V_NOISE", _F, 0.3, 0.01, 5.0),
    ("EKF2_HGT_REF", _I, 1, 0, 3),
    ("EKF2_MAG_TYPE", _I, 0, 0, 6),
    ("EKF2_REQ_EPH", _F, 3.0, 2.0, 100.0),
    ("EKF2_REQ_EPV", _F, 5.0, 2.0, 100.0),
    ("EKF2_REQ_NSATS", _I, 6, 4, 12),
    # battery
    ("BAT1_CAPACITY", _F, -1.0, -1.0, 100000.0),
    ("BAT1_N_CELLS", _I, 4, 1, 16),
    ("BAT1_SOURCE", _I, 0, -1, 2),
    ("BAT1_V_CHARGED", _F, 4.05, 0.0, 10.0),
    ("BAT1_V_EMPTY", _F, 3.6, 0.0, 10.0),
    ("BAT_AVRG_CURRENT", _F, 15.0, 0.0, 500.0),
    ("BAT_CRIT_THR", _F, 0.07, 0.05, 0.5),
    ("BAT_EMERGEN_THR", _F, 0.05, 0.03, 0.5),
    ("BAT_LOW_THR", _F, 0.15, 0.12, 0.5),
    # sensors and calibration (SITL's simulated sensors)
    ("CAL_ACC0_ID", _I, 1310988, 0, _BIG),
    ("CAL_ACC0_PRIO", _I, -1, -1, 100),
    ("CAL_BARO0_ID", _I, 6620172, 0, _BIG),
    ("CAL_GYRO0_ID", _I, 1310988, 0, _BIG),
    ("CAL_GYRO0_PRIO", _I, -1, -1, 100),
    ("CAL_MAG0_ID", _I, 197388, 0, _BIG),
    ("CAL_MAG0_PRIO", _I, -1, -1, 100),
    ("CAL_MAG0_ROT", _I, -1, -1, 40),
    ("SENS_BOARD_ROT", _I, 0, -1, 40),
    ("SENS_BOARD_X_OFF", _F, 0.0, -_BIG, _BIG),
    ("SENS_BOARD_Y_OFF", _F, 0.0, -_BIG, _BIG),
    ("SENS_BOARD_Z_OFF", _F, 0.0, -_BIG, _BIG),
    ("SENS_EN_GPSSIM", _I, 1, 0, 1),
    ("SENS_IMU_MODE", _I, 1, 0, 1),
    # radio calibration (SITL: no RC), airframe, safety
    ("RC_CHAN_CNT", _I, 0, 0, 18),
    ("RC_MAP_PITCH", _I, 0, 0, 18),
    ("RC_MAP_ROLL", _I, 0, 0, 18),
    ("RC_MAP_THROTTLE", _I, 0, 0, 18),
    ("RC_MAP_YAW", _I, 0, 0, 18),
    ("RC_MAP_FLTMODE", _I, 0, 0, 18),
    ("RC_MAP_KILL_SW", _I, 0, 0, 18),
    ("CA_AIRFRAME", _I, 0, 0, 15),
    ("CA_ROTOR_COUNT", _I, 4, 0, 12),
    ("CBRK_SUPPLY_CHK", _I, 894281, 0, 894281),
    ("CBRK_USB_CHK", _I, 197848, 0, 197848),
    ("CBRK_IO_SAFETY", _I, 22027, 0, 22027),
    ("COM_RCL_ACT_T", _F, 15.0, 0.0, 3600.0),
    ("SDLOG_MODE", _I, 0, -1, 4),
    ("SDLOG_PROFILE", _I, 1, 0, 4095),
    ("SIH_VEHICLE_TYPE", _I, 0, 0, 3),
    ("TRIG_MODE", _I, 0, 0, 4),
    ("UAVCAN_ENABLE", _I, 0, 0, 3),
)

#: Every parameter by name, in PX4's order (sorted by name: PX4's parameter index).
PX4_PARAMS: dict[str, ParamDef] = {
    row[0]: ParamDef(*row) for row in sorted(_TABLE, key=lambda row: row[0])}
