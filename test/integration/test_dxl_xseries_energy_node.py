"""X-series efforts end to end: a leg of three emulated XM430-W350s under gravity-like loads,
``dynamixel_driver`` reading them with the real dynamixel-sdk, ``energy_monitor`` finding the
cycles in the joint positions (no /gait/phase) and taking P_out from the efforts.

Before, the emulator wrote the servo model's PWM duty into Present Current: the efforts
followed the velocity's sign (no negative joint work), ``energy_monitor`` refused them as
torques and, with no gait schedule for its model, published P_out NaN in every window."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rclpy
from harness import Collector, ros_env
from hexapod_interfaces.msg import EnergeticDescriptors
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState, JointState

from hexapod_bench_drivers.control_tables import BACK_DRIVE_DEAD_BAND_RAD_S
from hexapod_bench_drivers.dynamixel_node import DynamixelDriverNode, DynamixelDriverParams
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator
from hexapod_energy.energy_node import EnergyMonitorNode

NAMES = ['L1_coxa', 'L1_femur', 'L1_tibia']
#: the loads on the three servos [N m]: the femur and tibia carry gravity-like torques
LOADS = [0.0, -1.0, 0.6]
PERIOD_S = 0.8
AMPLITUDE_RAD = [0.3, 0.35, 0.3]
P_IN_W = 24.0


def _time_mean(t_s, values):
    """Mean of samples each weighted by half the spans to its neighbours (energy_monitor's)."""
    w = np.empty_like(t_s)
    w[1:-1] = 0.5 * (t_s[2:] - t_s[:-2])
    w[0], w[-1] = t_s[1] - t_s[0], t_s[-1] - t_s[-2]
    return float(np.sum(w * values) / np.sum(w))


@pytest.mark.timeout(120)
def test_xm430_efforts_give_energy_monitor_its_p_out(tmp_path):
    joints = tmp_path / 'joints.yaml'
    joints.write_text('joints:\n' + ''.join(
        f'  {n}: {{id: {i + 1}, direction: 1}}\n' for i, n in enumerate(NAMES)))
    with ServoBusEmulator.of_model('XM430-W350', [1, 2, 3]) as emu, ros_env('xcur') as env:
        for k, load in enumerate(LOADS):
            emu.servo(k + 1).external_torque_nm = load
        driver = env.make(DynamixelDriverNode, parameter_overrides=[
            Parameter('port', value=emu.port_name), Parameter('protocol', value=2),
            Parameter('joints_file', value=str(joints)),
            Parameter('timeout_margin_ms', value=20.0)])
        env.make(EnergyMonitorNode, parameter_overrides=[
            Parameter('mass', value=1.5), Parameter('speed', value=0.1),
            Parameter('current_sign', value='ros'), Parameter('cycle_source', value='joints')])
        states = Collector(env, JointState, 'joint_states')
        out = Collector(env, EnergeticDescriptors, 'energy/descriptors')
        gait = env.add(rclpy.create_node('leg_gait', context=env.context,
                                         namespace=env.namespace))
        commands = gait.create_publisher(JointState, 'joint_commands', 10)
        battery = gait.create_publisher(BatteryState, 'battery_state', 10)
        t0 = gait.get_clock().now().nanoseconds * 1e-9

        def tick() -> None:   # the leg's gait and a 24 W battery, every 20 ms
            now = gait.get_clock().now()
            phase = 2.0 * math.pi * (now.nanoseconds * 1e-9 - t0) / PERIOD_S
            commands.publish(JointState(name=NAMES, position=[
                a * math.sin(phase - k) for k, a in enumerate(AMPLITUDE_RAD)]))
            b = BatteryState(voltage=12.0, current=-P_IN_W / 12.0)
            b.header.stamp = now.to_msg()
            battery.publish(b)
        gait.create_timer(0.02, tick)
        msgs = out.wait_for(env, 3, timeout_s=60.0)
    # each model's own gear efficiency (the XM430's 0.739), the default dead band
    assert driver.bus.gear_efficiency is None
    assert driver.bus.back_drive_dead_band_rad_s == BACK_DRIVE_DEAD_BAND_RAD_S
    t = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in states.messages])
    vel = np.array([m.velocity for m in states.messages])
    effort = np.array([m.effort for m in states.messages])
    power = vel * effort
    seen = [(m.window, m.power_in, m.power_out) for m in msgs]
    for m in msgs:
        assert m.window == pytest.approx(PERIOD_S, rel=0.05), seen
        assert m.power_in == pytest.approx(P_IN_W, rel=1e-6)
        # P_out from the efforts (NaN before: refused, no model without a gait schedule)
        assert math.isfinite(m.power_out) and 0.0 < m.power_out < m.power_in
        end = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
        inside = (t >= end - m.window) & (t < end)
        positive = _time_mean(t[inside], np.clip(power[inside], 0.0, None).sum(axis=1))
        net = _time_mean(t[inside], power[inside].sum(axis=1))
        # (equal when the node took every message the test did)
        assert m.power_out == pytest.approx(positive, rel=0.02), (seen, positive)
        assert net < 0.9 * positive, (net, positive)   # the joints absorb power
    # the femur's effort: the torque holding its 1 N m load, with the rotor's inertia torque
    # on top (the commands step every 20 ms), positive whichever way it moves: lowering,
    # its joint power is negative (runs: 72-91 % of those readings positive, median
    # 0.94-1.28 N m, the back-driven current divided by eta^2; one constant read 0.47-0.54;
    # lifting 0.97-1.20 N m; the old emulator: the velocity's sign)
    femur, femur_vel = effort[len(effort) // 3:, 1], vel[len(effort) // 3:, 1]
    lowering, lifting = femur_vel < -0.5, femur_vel > 0.5
    assert lowering.sum() > 20 and lifting.sum() > 20
    figures = (np.mean(femur[lowering] > 0), np.median(femur[lowering]),
               np.median(femur[lifting]))
    assert figures[0] > 0.6, figures
    assert 0.8 < figures[1] < 1.5 and 0.8 < figures[2] < 1.4, figures


@pytest.mark.timeout(60)
def test_the_driver_passes_its_gear_efficiency_to_the_bus(tmp_path):
    """``gear_efficiency`` (0: each model's own) and ``back_drive_dead_band_rad_s`` reach the
    bus; out-of-range values are refused at start-up."""
    from hexapod_common.errors import ParameterError
    from hexapod_common.node_utils import params_from_overrides

    joints = tmp_path / 'joints.yaml'
    joints.write_text('joints:\n  a: {id: 1}\n')
    with ServoBusEmulator.of_model('XM430-W350', [1]) as emu, ros_env('xeta') as env:
        driver = env.make(DynamixelDriverNode, parameter_overrides=[
            Parameter('port', value=emu.port_name), Parameter('protocol', value=2),
            Parameter('joints_file', value=str(joints)), Parameter('torque_on_start', value=False),
            Parameter('gear_efficiency', value=0.9),
            Parameter('back_drive_dead_band_rad_s', value=0.1)])
        assert driver.bus.gear_efficiency == 0.9
        assert driver.bus.back_drive_dead_band_rad_s == 0.1
    for name, value in (('gear_efficiency', 1.5), ('gear_efficiency', -0.1),
                        ('gear_efficiency', 0.07),
                        ('back_drive_dead_band_rad_s', -1.0),
                        ('back_drive_dead_band_rad_s', math.inf)):
        with pytest.raises(ParameterError, match=name):
            params_from_overrides(DynamixelDriverParams, [
                Parameter('joints_file', value='j.yaml'), Parameter(name, value=value)])


@pytest.mark.timeout(60)
def test_the_driver_warns_at_start_of_models_without_a_gear_efficiency(tmp_path):
    """An XH430-W350 (no gear efficiency known) and an XM430-W350 (its preset's 0.739): the
    start-up log warns, naming the XH430 and its ID, that its back-driven efforts are not
    corrected and how to give the driver a gear efficiency; with ``gear_efficiency`` 0.7 it
    says nothing of it. Before, nothing was said."""
    joints = tmp_path / 'joints.yaml'
    joints.write_text('joints:\n  a: {id: 1}\n  b: {id: 2}\n')

    class Captured(DynamixelDriverNode):
        def get_logger(self):
            log = super().get_logger()
            log.warning = lambda msg, **kw: lines.append(msg)
            return log

    for eta, expected in ((0.0, 1), (0.7, 0)):
        lines: list[str] = []
        with ServoBusEmulator.of_models([(1, 'XH430-W350'), (2, 'XM430-W350')]) as emu, \
                ros_env('xwarn') as env:
            env.make(Captured, parameter_overrides=[
                Parameter('port', value=emu.port_name), Parameter('protocol', value=2),
                Parameter('joints_file', value=str(joints)),
                Parameter('torque_on_start', value=False),
                Parameter('gear_efficiency', value=eta)])
        said = [w for w in lines if 'back-drive correction' in w]
        assert len(said) == expected, lines
        if said:
            assert said[0].startswith('XH430-W350 (id 1): no gear efficiency is known for this '
                                      'model'), said
            assert 'gear_efficiency' in said[0] and 'XM430-W350 (' not in said[0]
