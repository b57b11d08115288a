"""``energy_monitor`` on another lab's robot that publishes no ``/gait/phase``: only
``/joint_states`` (with efforts), ``/battery_state`` and ``odom``. The node finds the cycles in
the joint positions and publishes descriptors; they equal, window by window, the offline
analysis of the same run recorded in a bag (``read_robot_bag``)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Time
from harness import Collector, ros_env
from hexapod_interfaces.msg import EnergeticDescriptors
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import BatteryState, JointState

from hexapod_energy.bag_io import read_robot_bag
from hexapod_energy.energy_node import EnergyMonitorNode

_spec = importlib.util.spec_from_file_location(
    'nogait_bags', Path(__file__).parents[1] / 'unit' / 'test_outside_nogait_bag.py')
nogait_bags = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(nogait_bags)


def _stamp(t_s: float) -> Time:
    ns = int(round((nogait_bags.T0_S + t_s) * 1e9))
    return Time(sec=ns // 10**9, nanosec=ns % 10**9)


@pytest.mark.timeout(120)
def test_no_gait_phase_publisher_live_equals_offline(tmp_path):
    trace = nogait_bags.simulated_run(duration_s=8.0)
    period, speed = float(trace.period_s[0]), float(trace.speed_mps[0])
    nogait_bags.write_lab_bag(tmp_path / 'lab', trace)
    offline = read_robot_bag(tmp_path / 'lab', mass_kg=2.183, current_sign='ros')
    qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
    with ros_env('nogait') as env:
        env.make(EnergyMonitorNode, parameter_overrides=[
            Parameter('current_sign', value='ros'), Parameter('mass', value=2.183)])
        out = Collector(env, EnergeticDescriptors, 'energy/descriptors')
        lab = env.add(rclpy.create_node('lab_driver', context=env.context,
                                        namespace=env.namespace))
        pubs = {'joints': lab.create_publisher(JointState, 'joint_states', qos),
                'battery': lab.create_publisher(BatteryState, 'battery_state', qos),
                'odom': lab.create_publisher(Odometry, 'odom', qos)}
        assert env.spin_until(lambda: all(p.get_subscription_count() >= 1
                                          for p in pubs.values()), 20)
        for k, t in enumerate(trace.t_s):
            js = JointState(name=list(trace.joint_names),
                            position=trace.position_rad[k].tolist(),
                            velocity=trace.velocity_rad_s[k].tolist(),
                            effort=trace.effort_nm[k].tolist())
            js.header.stamp = _stamp(t)
            pubs['joints'].publish(js)
            if k % 2 == 0:
                b = BatteryState(voltage=float(trace.battery_voltage_v[k]),
                                 current=float(trace.battery_current_a[k]))
                b.header.stamp = _stamp(t)
                pubs['battery'].publish(b)
                o = Odometry(child_frame_id='base_link')
                o.header.stamp, o.header.frame_id = _stamp(t), 'odom'
                o.pose.pose.position.x = speed * t + nogait_bags.WOBBLE_M * np.sin(
                    2 * np.pi * t / period)
                pubs['odom'].publish(o)
            for _ in range(4):
                env.executor.spin_once(timeout_sec=0.0)
        expected = offline.extra['windows']
        msgs = out.wait_for(env, len(expected), timeout_s=30)
    assert len(expected) >= 6 and len(msgs) == len(expected)
    for m, d in zip(msgs, expected):
        assert m.window == pytest.approx(period, rel=0.01)
        # same core fed the same stream: equal to rounding (stated tolerance 1e-9)
        for field, ref in (('window', d.window_s), ('power_in', d.power_in_w),
                           ('speed', d.speed_mps)):
            assert getattr(m, field) == pytest.approx(ref, rel=1e-9, abs=1e-9), field
        # read_robot_bag keeps the raw effort P_out for the command to judge; the node in
        # 'auto' refuses these efforts (the simulated AX servos' PWM load never does negative
        # work) and, with no gait for the model, publishes P_out unknown
        assert d.power_out_w > 0 and d.joint_power_net_w >= 0.9 * d.power_out_w
        assert np.isnan(m.power_out) and np.isnan(m.efficiency)
        assert m.speed == pytest.approx(speed, rel=0.02)
