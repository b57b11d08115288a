"""dynamixel_driver node on the emulated bus: rate, commands, torque service, faults, diagnostics."""

from __future__ import annotations

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
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


@pytest.mark.timeout(90)
def test_refused_servos_in_diagnostics_and_the_torque_service(tmp_path):
    """Two XM430s, an unknown model (350, as an XL-320 reports), a servo at Status Return
    Level 0 and one in velocity mode. Diagnostics: ERROR 'left out' with the refusal for the
    first two, WARN naming the mode for the third (all read 'ok' before); the torque service
    succeeds for the usable servos and names the refused ones (it could never succeed)."""
    import dataclasses

    from hexapod_bench_drivers.control_tables import XM430
    from hexapod_bench_drivers.servo_bus_emulator import EmulatedServo

    servos = [EmulatedServo(i, XM430) for i in (1, 2, 4, 5)]
    servos.insert(2, EmulatedServo(3, dataclasses.replace(XM430, model_name='XL-320',
                                                           model_number=350)))
    servos[3].set('status_return_level', 0)
    servos[4].set('operating_mode', 1)
    names = ['a', 'b', 'c', 'd', 'e']
    joints = tmp_path / 'joints.yaml'
    joints.write_text('joints:\n' + ''.join(f'  {n}: {{id: {i}}}\n'
                                            for i, n in enumerate(names, 1)))
    with ServoBusEmulator(servos) as emu, ros_env('dxl') as env:
        node = _node(env, emu, str(joints), 2, torque_on_start=False, diagnostics_period_s=0.1)
        diags = Collector(env, DiagnosticArray, '/diagnostics')
        diags.wait_for(env, 1)
        status = {s.name.split(': ')[-1]: s for s in diags.messages[-1].status}
        levels = {n: status[n].level for n in names}
        assert levels == {'a': DiagnosticStatus.OK, 'b': DiagnosticStatus.OK,
                          'c': DiagnosticStatus.ERROR, 'd': DiagnosticStatus.ERROR,
                          'e': DiagnosticStatus.WARN}
        assert status['c'].message.startswith('left out: unknown Dynamixel model number 350')
        assert 'Status Return Level is 0' in status['d'].message
        assert 'Operating Mode 1 (velocity control)' in status['e'].message

        client = node.create_client(SetBool, 'set_torque')
        fut = client.call_async(SetBool.Request(data=True))
        env.executor.spin_until_future_complete(fut, timeout_sec=10.0)
        assert fut.done() and fut.result().success
        assert "left out (refused): ['c', 'd', 'e']" in fut.result().message
        assert [emu.read_register(i, 'torque_enable') for i in (1, 2, 3, 4, 5)] == [1, 1, 0,
                                                                                      0, 0]


def _set_parameter(env, node, name, value):
    """One SetParameters request through the node's service, as ``ros2 param set`` sends it."""
    from rcl_interfaces.srv import SetParameters

    client = node.create_client(SetParameters, f'{node.get_fully_qualified_name()}'
                                                '/set_parameters')
    fut = client.call_async(SetParameters.Request(
        parameters=[Parameter(name, value=value).to_parameter_msg()]))
    env.executor.spin_until_future_complete(fut, timeout_sec=10.0)
    assert fut.done()
    node.destroy_client(client)
    return fut.result().results[0]


@pytest.mark.timeout(90)
def test_run_time_temperature_limit_applies_and_bus_settings_are_read_only(tmp_path):
    """temperature_limit_c set to 40 at run time stops a servo at 55 degC (the bus used to
    keep 70); NaN is refused; settings the bus took at start-up are refused with a reason."""
    names = NAMES[:3]
    with ServoBusEmulator.of_model('ax18a', range(1, 4)) as emu, ros_env('dxl') as env:
        node = _node(env, emu, _joint_file(tmp_path, names), 1)
        states = Collector(env, JointState, 'joint_states')
        states.wait_for(env, 5)
        for name, value in [('rate_hz', 1.0), ('port', '/dev/null'), ('baud_rate', 57600),
                            ('retries', 5), ('timeout_margin_ms', 50.0), ('silent_after', 9),
                            ('probe_interval_s', 9.0), ('diagnostics_period_s', 9.0)]:
            result = _set_parameter(env, node, name, value)
            assert not result.successful and 'read-only' in result.reason, name
        nan = _set_parameter(env, node, 'temperature_limit_c', float('nan'))
        assert not nan.successful and 'finite' in nan.reason
        assert node.bus.temperature_limit_c == 70.0
        emu.inject(2, 'overheat', temperature_c=55)
        n = len(states.messages)
        assert env.spin_until(lambda: len(states.messages) >= n + 10, 30.0)
        assert not node.bus.aborted                      # 55 degC is below the 70 degC limit
        result = _set_parameter(env, node, 'temperature_limit_c', 40.0)
        assert result.successful
        assert node.bus.temperature_limit_c == 40.0
        assert env.spin_until(lambda: node.bus.aborted, 30.0)
        assert 'limit 40 degC' in node.bus.abort_reason
        assert [emu.read_register(i, 'torque_enable') for i in (1, 2, 3)] == [0, 0, 0]


@pytest.mark.parametrize('limit', [float('nan'), float('inf'), -5.0])
def test_a_temperature_limit_that_can_never_fire_is_refused_at_start_up(limit):
    from hexapod_common.errors import ParameterError
    from hexapod_common.node_utils import params_from_overrides

    from hexapod_bench_drivers.dynamixel_node import DynamixelDriverParams

    with pytest.raises(ParameterError, match='temperature_limit_c'):
        params_from_overrides(DynamixelDriverParams,
                              [Parameter('temperature_limit_c', value=limit),
                               Parameter('joints_file', value='j.yaml')])
