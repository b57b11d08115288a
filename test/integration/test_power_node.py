"""power_monitor node: ROS sign convention, zero-offset calibration, SCPI backend on a pty."""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import pytest
from harness import Collector, ros_env
from numpy.testing import assert_allclose
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState

from hexapod_bench_drivers.power_backends import SimPowerBackend
from hexapod_bench_drivers.power_node import PowerMonitorNode

sys.path.insert(0, str(Path(__file__).parents[1] / 'unit'))
from test_power_backends import ScpiPeer  # noqa: E402


@pytest.mark.timeout(60)
def test_zero_offset_then_negative_current_when_drawing():
    counter = itertools.count()
    # 10 readings unpowered (0.05 A sensor offset), then the robot draws 1.5 A.
    backend = SimPowerBackend(12.0, lambda: 0.05 if next(counter) < 10 else 1.55)
    with ros_env('power') as env:
        env.make(PowerMonitorNode, backend=backend, parameter_overrides=[
            Parameter('zero_offset_samples', value=10), Parameter('rate_hz', value=200.0)])
        msgs = Collector(env, BatteryState, 'battery_state').wait_for(env, 5)
        assert_allclose([m.current for m in msgs], -1.5, atol=1e-6)
        assert_allclose([m.voltage for m in msgs], 12.0, rtol=1e-6)
        assert all(m.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
                   for m in msgs)


@pytest.mark.timeout(60)
def test_scpi_backend_through_parameters():
    peer = ScpiPeer(11.85, 0.75)
    try:
        with ros_env('power') as env:
            env.make(PowerMonitorNode, parameter_overrides=[
                Parameter('backend', value='scpi'), Parameter('serial_port', value=peer.port),
                Parameter('rate_hz', value=50.0)])
            msgs = Collector(env, BatteryState, 'battery_state').wait_for(env, 3)
            assert_allclose([m.voltage for m in msgs], 11.85, rtol=1e-6)
            assert_allclose([m.current for m in msgs], -0.75, rtol=1e-6)
    finally:
        peer.close()


@pytest.mark.timeout(60)
def test_run_time_rate_change_is_refused_frame_id_applies():
    """rate_hz sets the timer once: a run-time change is refused (it used to be accepted while
    the timer kept 100 Hz); frame_id is read for every message and applies."""
    with ros_env('power') as env:
        node = env.make(PowerMonitorNode, backend=SimPowerBackend(12.0, 1.0))
        msgs = Collector(env, BatteryState, 'battery_state')
        [rate] = node.set_parameters([Parameter('rate_hz', value=1.0)])
        assert not rate.successful and 'read-only' in rate.reason
        assert [t.timer_period_ns for t in node.timers] == [10_000_000]
        [frame] = node.set_parameters([Parameter('frame_id', value='supply')])
        assert frame.successful
        n = len(msgs.messages)
        msgs.wait_for(env, n + 2)
        assert msgs.messages[-1].header.frame_id == 'supply'
