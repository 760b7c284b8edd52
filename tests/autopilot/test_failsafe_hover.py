"""Each autopilot's failsafe settings for a vehicle that must hover when its station is lost
(its column meets another's) and for one that lands, and what the record says of them."""

from __future__ import annotations

from gcs.autopilot import ardupilot, px4
from gcs.flight.procedure.failsafe import failsafe_record


def test_px4_hovers_on_hold_and_lands_otherwise() -> None:
    own = {"COM_OF_LOSS_T": 1.0, "COM_FAIL_ACT_T": 5.0, "COM_OBL_RC_ACT": 0.0}
    assert px4.PX4.failsafe_settings(own, 5.0, hover=True) == {"COM_OBL_RC_ACT": px4.OBL_HOLD}
    assert px4.PX4.failsafe_settings(own, 7.6) == {"COM_OBL_RC_ACT": px4.OBL_LAND,
                                                   "COM_FAIL_ACT_T": 7.6}
    hover = px4.PX4.failsafe({**own, "COM_OBL_RC_ACT": px4.OBL_HOLD})
    assert failsafe_record(hover) == {"loss_timeout": 1.0, "action_delay": 5.0,
                                      "action": "Hold"}


def test_ardupilot_hovers_with_its_gcs_failsafe_off_and_lands_otherwise() -> None:
    own = {"FS_GCS_ENABLE": 1.0, "FS_GCS_TIMEOUT": 5.0, "GUID_TIMEOUT": 3.0}
    settings = ardupilot.ARDUPILOT.failsafe_settings(own, 5.0, hover=True)
    assert settings == {"FS_GCS_ENABLE": ardupilot.FS_GCS_HOLD}
    hover = ardupilot.ARDUPILOT.failsafe({**own, **settings})
    # it holds its last position target for good: no delay to tell, and no Infinity in JSON
    assert failsafe_record(hover) == {"loss_timeout": 3.0, "action_delay": None,
                                      "action": "Hold"}
    assert ardupilot.ARDUPILOT.failsafe_settings(own, 5.0) == {
        "FS_GCS_ENABLE": ardupilot.FS_GCS_LAND}
