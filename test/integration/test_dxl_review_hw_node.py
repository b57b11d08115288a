"""dynamixel_driver node, fixes from the outside hardware review against an independent
emulator (/tmp/rev_dxl/REPORT.md): a Protocol 1.0 Alarm Shutdown (Torque Limit 0) and goals
clipped to the angle limits on /diagnostics; the exit code and wording of torque off at
shutdown."""

from __future__ import annotations

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from harness import Collector, ros_env
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from hexapod_bench_drivers.dynamixel_node import DynamixelDriverNode
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator


def _node(env, emu, tmp_path, protocol, n=2, **extra):
    path = tmp_path / 'joints.yaml'
    path.write_text('joints:\n' + ''.join(f'  j{i}: {{id: {i}}}\n' for i in range(1, n + 1)))
    overrides = [Parameter('port', value=emu.port_name), Parameter('protocol', value=protocol),
                 Parameter('joints_file', value=str(path)),
                 Parameter('timeout_margin_ms', value=20.0),
                 Parameter('diagnostics_period_s', value=0.1)]
    overrides += [Parameter(k, value=v) for k, v in extra.items()]
    return env.make(DynamixelDriverNode, parameter_overrides=overrides)


def _status(diags, name):
    return next(s for s in diags.messages[-1].status if s.name.endswith(f': {name}'))


def _values(status):
    return {kv.key: kv.value for kv in status.values}


@pytest.mark.timeout(90)
def test_p1_alarm_shutdown_error_on_diagnostics(tmp_path):
    """AX-18A j2 overloads, its flag clears with the load: Torque Limit stays 0, limp. Before:
    'ok', torque_enabled True. Now ERROR naming register 34 and Alarm Shutdown until
    set_torque(True) writes Torque Limit back."""
    with ServoBusEmulator.of_model('ax18a', [1, 2]) as emu, ros_env('dxl_hw') as env:
        node = _node(env, emu, tmp_path, 1)
        diags = Collector(env, DiagnosticArray, '/diagnostics')
        diags.wait_for(env, 1)
        emu.inject(2, 'error_bits', error_bits=0x20)
        assert env.spin_until(lambda: node.bus.health()[1].torque_lost != '', 30.0)
        emu.clear_faults(2)
        n = len(diags.messages)
        assert env.spin_until(lambda: len(diags.messages) >= n + 2, 30.0)
        j2 = _status(diags, 'j2')
        assert j2.level == DiagnosticStatus.ERROR
        assert 'Torque Limit (register 34) reads 0' in j2.message
        assert 'Alarm Shutdown' in j2.message
        assert _values(j2)['torque_enabled'] == 'False'
        assert _status(diags, 'j1').level == DiagnosticStatus.OK
        assert emu.read_register(2, 'torque_enable') == 1     # what the old driver read
        node.bus.set_torque(True)
        assert emu.read_register(2, 'torque_limit') == 1023
        n = len(diags.messages)
        assert env.spin_until(lambda: len(diags.messages) >= n + 2, 30.0)
        assert _status(diags, 'j2').level == DiagnosticStatus.OK


@pytest.mark.timeout(90)
def test_goals_clipped_warn_on_diagnostics_with_the_count(tmp_path):
    """j1 limited to ticks 300..700 and commanded 1.2 rad: WARN with the count and the limit
    while it lasts (before: 'ok', the goal refused by the servo), OK after a goal inside."""
    with ServoBusEmulator.of_model('ax18a', [1, 2]) as emu, ros_env('dxl_hw') as env:
        emu.servo(1).set('cw_angle_limit', 300)
        emu.servo(1).set('ccw_angle_limit', 700)
        node = _node(env, emu, tmp_path, 1)
        diags = Collector(env, DiagnosticArray, '/diagnostics')
        diags.wait_for(env, 1)
        pub = node.create_publisher(JointState, 'joint_commands', 10)
        out = JointState(name=['j1', 'j2'], position=[1.2, 0.2])

        def clipped(k):
            pub.publish(out)
            return node.bus.health()[0].goals_clipped >= k
        assert env.spin_until(lambda: clipped(3), 30.0)
        n = len(diags.messages)
        assert env.spin_until(lambda: len(diags.messages) >= n + 1, 30.0)
        j1 = _status(diags, 'j1')
        assert j1.level == DiagnosticStatus.WARN
        count = int(_values(j1)['goals_clipped'])
        assert count >= 3 and j1.message.startswith(f'{count} goals clipped so far: goal 1.200 '
                                                    'rad beyond its limit 0.962 rad')
        assert _status(diags, 'j2').level == DiagnosticStatus.OK
        assert emu.read_register(1, 'goal_position') == 700
        inside = JointState(name=['j1'], position=[0.1])

        def back():
            pub.publish(inside)
            return node.bus.health()[0].goal_clip == ''
        assert env.spin_until(back, 30.0)
        n = len(diags.messages)
        assert env.spin_until(lambda: len(diags.messages) >= n + 2, 30.0)
        assert _status(diags, 'j1').level == DiagnosticStatus.OK


@pytest.mark.timeout(90)
def test_left_out_servos_named_as_never_written_at_shutdown(tmp_path):
    """AX-18A j2 at Status Return Level 0 (left out, its model unread on Protocol 1.0) and j3
    of an unknown model (left out): the shutdown line named them 'not confirmed: they may
    still hold their position' though the driver never wrote them. Now j3 is 'left out, never
    written; torque state unknown' (a warning) and j2 is sent Torque Enable 0 at 24 without a
    reply (every described 1.0 model has it there), also a warning; the exit code stays 0
    since every servo the driver wrote confirmed."""
    import dataclasses

    from hexapod_bench_drivers.control_tables import AX18A
    from hexapod_bench_drivers.servo_bus_emulator import EmulatedServo

    servos = [EmulatedServo(1, AX18A), EmulatedServo(2, AX18A),
              EmulatedServo(3, dataclasses.replace(AX18A, model_number=999))]
    with ServoBusEmulator(servos) as emu, ros_env('dxl_hw') as env:
        emu.servo(2).set('status_return_level', 0)
        emu.servo(2).set('torque_enable', 1)
        emu.servo(3).set('torque_enable', 1)
        node = _node(env, emu, tmp_path, 1, n=3, retries=0)
        lines = []
        log = node.get_logger()
        for level in ('info', 'warning', 'error'):
            setattr(log, level, lambda msg, _lv=level, **kw: lines.append((_lv, msg)))
        env.nodes.remove(node)
        env.executor.remove_node(node)
        node.destroy_node()
        assert ('warning', 'j3: left out, never written; torque state unknown') in lines
        assert ('warning', 'torque off at shutdown sent without a reply to j2 (left out at '
                'Status Return Level 0: the servo carries out writes but never answers): not '
                'confirmed') in lines
        assert ('info', 'torque off on 1 servo(s)') in lines
        assert not [m for lv, m in lines if lv == 'error']
        assert node.exit_code_on_stop == 0
        assert env.spin_until(lambda: emu.read_register(2, 'torque_enable') == 0, 10.0)
        assert emu.read_register(3, 'torque_enable') == 1
