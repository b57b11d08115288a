"""dynamixel_driver node on the emulated bus: rate, commands, torque service, faults, diagnostics."""

from __future__ import annotations

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from harness import Collector, ros_env
from hexapod_interfaces.msg import ServoStatus
from numpy.testing import assert_allclose
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool

from hexapod_bench_drivers.dynamixel_node import DynamixelDriverNode
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator

LEGS = ['L1', 'L2', 'L3', 'R1', 'R2', 'R3']
NAMES = [f'{leg}_{j}' for leg in LEGS for j in ('coxa', 'femur', 'tibia')]


def _joint_file(tmp_path, names):
    path = tmp_path / 'joints.yaml'
    path.write_text('joints:\n' + ''.join(
        f'  {n}: {{id: {i + 1}, direction: {-1 if n.startswith("R") else 1}}}\n'
        for i, n in enumerate(names)))
    return str(path)


def _node(env, emu, joints_file, protocol, **extra):
    overrides = [Parameter('port', value=emu.port_name), Parameter('protocol', value=protocol),
                 Parameter('joints_file', value=joints_file),
                 Parameter('timeout_margin_ms', value=20.0)]
    overrides += [Parameter(k, value=v) for k, v in extra.items()]
    return env.make(DynamixelDriverNode, parameter_overrides=overrides)


@pytest.mark.timeout(90)
@pytest.mark.parametrize('model,protocol,n', [('ax18a', 1, 18), ('xl430', 2, 4)])
def test_states_for_all_servos_and_commands_move(tmp_path, model, protocol, n):
    names = NAMES[:n]
    with ServoBusEmulator.of_model(model, range(1, n + 1)) as emu, ros_env('dxl') as env:
        node = _node(env, emu, _joint_file(tmp_path, names), protocol)
        states = Collector(env, JointState, 'joint_states')
        status = Collector(env, ServoStatus, 'servo_status')
        states.wait_for(env, 20)
        status.wait_for(env, 20)
        msg = states.messages[-1]
        assert list(msg.name) == names
        assert len(msg.position) == len(msg.velocity) == len(msg.effort) == n
        assert list(status.messages[-1].name) == names
        assert_allclose(status.messages[-1].temperature, 26.0)
        assert_allclose(status.messages[-1].voltage, 12.0, rtol=1e-6)
        # Stamps strictly increase: one message per read cycle.
        stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in states.messages]
        assert all(b > a for a, b in zip(stamps, stamps[1:]))

        targets = [0.25 if k % 2 else -0.2 for k in range(n)]
        pub = node.create_publisher(JointState, 'joint_commands', 10)
        cmd = JointState(name=names + ['not_on_this_bus'], position=targets + [1.0])

        def arrived():
            pub.publish(cmd)
            last = states.messages[-1]
            return all(abs(p - t) < 0.05 for p, t in zip(last.position, targets))
        assert env.spin_until(arrived, 30.0)
        # The reversed right-side joints turned the emulated servos the other way.
        if n > 9:
            assert_allclose(emu.present_position_rad(10), -targets[9], atol=0.08)
        assert node.commands_applied > 0


@pytest.mark.timeout(90)
def test_torque_service_silent_servo_and_overheat_diagnostics(tmp_path):
    names = NAMES[:6]
    with ServoBusEmulator.of_model('ax18a', range(1, 7)) as emu, ros_env('dxl') as env:
        node = _node(env, emu, _joint_file(tmp_path, names), 1, torque_on_start=False,
                     diagnostics_period_s=0.1, temperature_limit_c=70.0)
        diags = Collector(env, DiagnosticArray, '/diagnostics')
        states = Collector(env, JointState, 'joint_states')
        client = node.create_client(SetBool, 'set_torque')
        fut = client.call_async(SetBool.Request(data=True))
        env.executor.spin_until_future_complete(fut, timeout_sec=10.0)
        assert fut.done() and fut.result().success
        assert [emu.read_register(i, 'torque_enable') for i in range(1, 7)] == [1] * 6

        silent = names[3]                       # id 4
        emu.inject(4, 'no_answer')
        assert env.spin_until(lambda: any(
            s.name.endswith(silent) and 'silent' in s.message
            for m in diags.messages[-3:] for s in m.status), 30.0)
        n_before = len(states.messages)
        assert env.spin_until(lambda: len(states.messages) >= n_before + 10, 30.0)
        # The other five are still published; the silent one is left out of joint_states.
        assert list(states.messages[-1].name) == [n for n in names if n != silent]

        emu.inject(2, 'overheat', temperature_c=72)
        assert env.spin_until(lambda: node.bus.aborted, 30.0)
        assert [emu.read_register(i, 'torque_enable') for i in (1, 2, 3, 5, 6)] == [0] * 5
        assert env.spin_until(lambda: any(
            'aborted' in s.message for m in diags.messages[-2:] for s in m.status), 30.0)
        values = {kv.key: kv.value for s in diags.messages[-1].status
                  if s.name.endswith(silent) for kv in s.values}
        assert int(values['timeouts']) >= 3 and values['model'] == 'AX-18A'
