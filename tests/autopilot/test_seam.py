"""The autopilot seam: detection from HEARTBEAT.autopilot, the fleet file's override, and the
facts each autopilot gives the procedure."""

from __future__ import annotations

import math

import pytest

from gcs import autopilot
from gcs.autopilot import ardupilot, px4
from gcs.autopilot.base import BOARDING_STEPS, Autopilot
from gcs.flight.procedure.failsafe import LAYER_BASE_DELAY_S
from gcs.wire import mavlink


def test_detection_by_heartbeat() -> None:
    assert autopilot.choose("auto", 12) is px4.PX4
    assert autopilot.choose("auto", 3) is ardupilot.ARDUPILOT
    assert autopilot.by_heartbeat(mavlink.MAV_AUTOPILOT_PX4) is px4.PX4
    assert autopilot.by_heartbeat(mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA) is ardupilot.ARDUPILOT
    why = autopilot.choose("auto", mavlink.MAV_AUTOPILOT_GENERIC)
    assert isinstance(why, str) and "autopilot type 0" in why and "px4 | ardupilot" in why


def test_override_names_one_or_refuses_the_other() -> None:
    """The fleet file's name flies a vehicle whose HEARTBEAT names no known autopilot, and is
    refused (with the fix) when its HEARTBEAT names the other one."""
    assert autopilot.choose("ardupilot", mavlink.MAV_AUTOPILOT_GENERIC) is ardupilot.ARDUPILOT
    assert autopilot.choose("px4", 12) is px4.PX4
    why = autopilot.choose("px4", 3)
    assert isinstance(why, str) and "says ArduPilot" in why and "fix the fleet file" in why


def test_px4_modes_are_encoded_as_ever() -> None:
    assert px4.PX4.follow_mode == px4.OFFBOARD and px4.OFFBOARD.custom_mode == 6 << 16
    assert px4.PX4.decode_mode(4 << 16 | 3 << 24) == px4.HOLD
    assert px4.PX4.land_mode.name == "AUTO.LAND"


def test_ardupilot_modes_are_copter_numbers() -> None:
    ap = ardupilot.ARDUPILOT
    assert ap.follow_mode.custom_mode == 4 and ap.follow_mode.command_params == (1.0, 4.0, 0.0)
    assert (ap.land_mode.custom_mode, ap.hold_mode.custom_mode, ap.rtl_mode.custom_mode) == \
        (9, 17, 6)
    assert ap.decode_mode(17).name == "BRAKE" and ap.decode_mode(99).name == "MODE(99)"
    assert ap.decode_mode(4) != px4.PX4.decode_mode(4)  # modes of two autopilots never equal


@pytest.mark.parametrize("kind", list(autopilot.AUTOPILOTS.values()), ids=lambda k: k.key)
def test_boarding_ends_following_setpoints(kind: Autopilot) -> None:
    """Every boarding is made of known steps, switches to the mode that follows setpoints
    before arming (both refuse otherwise) and ends with the streamed climb."""
    assert set(kind.boarding) <= set(BOARDING_STEPS)
    assert kind.boarding.index("follow") < kind.boarding.index("arm")
    assert kind.boarding[-1] == "climb"
    assert kind.message_rates(30.0)[mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED] == 30.0


def test_ardupilot_takes_off_by_command_after_an_origin() -> None:
    steps = ardupilot.ARDUPILOT.boarding
    assert steps.index("origin") < steps.index("arm") < steps.index("takeoff") < \
        steps.index("climb")
    assert "takeoff" not in px4.PX4.boarding and "prestream" not in steps


def test_layered_failsafe_starts_at_both_defaults() -> None:
    """The lowest layer lands after the default delay of both autopilots' failsafes."""
    assert LAYER_BASE_DELAY_S == px4.COM_FAIL_ACT_T_S == ardupilot.FS_GCS_TIMEOUT_S


def test_px4_failsafe_settings() -> None:
    values = {"COM_OF_LOSS_T": 1.0, "COM_FAIL_ACT_T": 5.0, "COM_OBL_RC_ACT": 0.0}
    assert px4.PX4.failsafe_settings(values, 6.2) == {"COM_OBL_RC_ACT": px4.OBL_LAND,
                                                      "COM_FAIL_ACT_T": 6.2}
    after = {**values, "COM_OBL_RC_ACT": 4.0}
    assert px4.PX4.failsafe(after).text() == ("after 1 s without setpoints: Position hold for "
                                              "5 s, then Land")


def test_ardupilot_failsafe_settings() -> None:
    """FS_GCS_ENABLE off (its default) holds the last target for good; set to Land it lands
    FS_GCS_TIMEOUT after the station's last HEARTBEAT."""
    ap = ardupilot.ARDUPILOT
    values = {"FS_GCS_ENABLE": 0.0, "FS_GCS_TIMEOUT": 5.0, "GUID_TIMEOUT": 3.0}
    off = ap.failsafe(values)
    assert off.effective == "Hold" and math.isinf(off.hold_s) and "for good" in off.text()
    assert ap.failsafe_settings(values, 7.0) == {"FS_GCS_ENABLE": 5.0, "FS_GCS_TIMEOUT": 7.0}
    on = ap.failsafe({**values, "FS_GCS_ENABLE": 5.0, "FS_GCS_TIMEOUT": 7.0})
    assert (on.loss_timeout, on.action_delay, on.effective, on.hold_s) == (3.0, 4.0, "Land", 7.0)
    assert ap.fence_enable == {"FENCE_ENABLE": ("f", 1.0)} and not px4.PX4.fence_enable
