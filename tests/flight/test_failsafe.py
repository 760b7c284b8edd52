"""The vehicles' own link-loss failsafe: read and set over MAVLink's parameter protocol
before arming (`gcs.flight.procedure.failsafe`), on the mock, which acts on it as PX4 does."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from gcs.autopilot import px4
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.setpoints import hold_track
from gcs.flight.procedure.failsafe import (
    ParamError,
    layer_delays,
    read_param,
    set_param,
    stacked_columns,
)
from gcs.sim import MockFleet
from gcs.wire import mavlink
from tests.flight.flying import stream_setpoint
from tests.flight.support import FAST_MOCK, STACKED, mock_ports, smooth_plan

pytestmark = pytest.mark.timeout(60)

def test_layers_land_lowest_first_and_stacked_columns_are_found() -> None:
    """The lower layer keeps PX4's 5 s; the upper one waits until the lower one (1.08 m at
    0.7 m/s) has had time to land, and 1 s more. The pair is found 0.55 m apart in columns;
    3 m apart, not."""
    plan = smooth_plan(STACKED)
    low, high = layer_delays(plan, 0.7)
    assert low == px4.COM_FAIL_ACT_T_S
    assert high == pytest.approx(5.0 + 1.08 / 0.7 + 1.0, abs=0.05)
    assert stacked_columns(plan, 1.0) == ("low", "high", pytest.approx(0.55), 0.0)
    apart = {**STACKED, "vehicles": [{**v, "start": [1.0 + 3 * n, 1.0, v["start"][2]],
                                      "goal": [1.0 + 3 * n, 3.0, v["goal"][2]]}
                                     for n, v in enumerate(STACKED["vehicles"])]}
    assert stacked_columns(smooth_plan(apart), 1.0) is None
    assert layer_delays(smooth_plan(apart), 0.7)[0] == px4.COM_FAIL_ACT_T_S


#: Two vehicles crossing 1 m apart in height and 0.5 m apart sideways, their columns nearest
#: at 1.75 s: between two of the 10 Hz samples, which see them 0.529 m apart at best.
CROSSING = {
    "name": "crossing", "dt": 0.25, "steps": 15, "min_separation": 0.6,
    "limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [5.0, 5.0, 3.0],
               "velocity_max": [3.0, 3.0, 3.0], "acceleration_max": [4.0, 4.0, 4.0]},
    "vehicles": [{"id": "a", "start": [0.5, 2.0, 1.0], "goal": [4.5, 2.0, 1.0]},
                 {"id": "b", "start": [4.5, 2.5, 2.0], "goal": [0.5, 2.5, 2.0]}],
}


def test_columns_that_meet_between_two_samples_are_found() -> None:
    """Columns 0.5 m apart at 1.75 s, 0.529 m at the nearest 10 Hz sample: with a clearance
    of 0.565 m (they meet below 0.515 m) the pair is found, with the instant and the gap
    between the samples."""
    plan = smooth_plan(CROSSING)
    times = np.arange(0.0, plan.scenario.horizon + 1e-9, 0.1)
    p = plan.sample(times).position
    assert np.linalg.norm(p[0, :, :2] - p[1, :, :2], axis=1).min() > 0.515  # samples miss it
    assert stacked_columns(plan, 0.565) == ("a", "b", pytest.approx(0.5, abs=1e-3),
                                            pytest.approx(1.75, abs=0.01))
    assert stacked_columns(plan, 0.54) is None  # 0.49 m is not reached


def test_a_failsafe_set_over_mavlink_is_what_the_vehicle_does() -> None:
    """COM_OBL_RC_ACT read (PX4's 0) and set to Hold (5) and COM_FAIL_ACT_T to 0.5 s over the
    parameter protocol: once its setpoints stop, the vehicle holds in Position for 0.5 s,
    then switches to Hold and stays in the air; an unknown parameter is a ParamError."""
    async def main() -> None:
        async with MockFleet(1, settle_time=0.2, **{**FAST_MOCK, "status_rate": 20.0},
                             **mock_ports(1)) as mock, LinkHub() as hub:
            link = await hub.add("v0", mock.gcs_url(0), 1)
            assert await link.wait_for(lambda t: t.position_ned is not None, 5.0)
            assert await read_param(link, "COM_OBL_RC_ACT", "i") == 0
            assert await read_param(link, "COM_FAIL_ACT_T", "f") == px4.COM_FAIL_ACT_T_S
            assert await set_param(link, "COM_OBL_RC_ACT", "i", 5) == 5
            assert await set_param(link, "COM_FAIL_ACT_T", "f", 0.5) == 0.5
            with pytest.raises(ParamError, match="NOT_A_PARAM not answered"):
                await read_param(link, "NOT_A_PARAM", "f")
            vehicle = mock.vehicles[0]
            setpoint = hold_track([0, 0, -1.5], 0.0, 20).at(0)

            streaming = asyncio.create_task(stream_setpoint(link, setpoint))
            assert await link.wait_for(lambda _t: vehicle.setpoints_accepted > 0
                                       and mock.now() >= mock.config.settle_time, 2.0)
            assert await link.command(mavlink.MAV_CMD_DO_SET_MODE,
                                      px4.OFFBOARD.command_params) == 0
            assert await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)) == 0
            assert await link.wait_for(lambda _t: vehicle.in_air, 5.0)
            streaming.cancel()
            assert await link.wait_for(lambda t: t.mode == px4.POSITION, 3.0)
            assert await link.wait_for(lambda t: t.mode == px4.HOLD, 3.0)
            held = next(t for t, e in vehicle.events if e == "failsafe: Hold")
            began = next(t for t, e in vehicle.events if e == "failsafe: offboard loss")
            assert held - began >= 0.5
            await asyncio.sleep(1.0)
            assert vehicle.armed and vehicle.mode == px4.HOLD and vehicle.in_air

    asyncio.run(main())
