"""dynamixel_driver node, outside-review fixes: the port lost at run time (F4), a power-cycled
servo in /diagnostics and the log (F1, F8)."""

from __future__ import annotations

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from harness import Collector, capture_errors, ros_env
from rclpy.parameter import Parameter

from hexapod_bench_drivers.dynamixel_node import EXIT_PORT_LOST, DynamixelDriverNode
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator


def _node(env, emu, tmp_path, protocol, **extra):
    path = tmp_path / 'joints.yaml'
    path.write_text('joints:\n  j1: {id: 1}\n  j2: {id: 2}\n')
    overrides = [Parameter('port', value=emu.port_name), Parameter('protocol', value=protocol),
                 Parameter('joints_file', value=str(path)),
                 Parameter('timeout_margin_ms', value=20.0),
                 Parameter('diagnostics_period_s', value=0.1)]
    overrides += [Parameter(k, value=v) for k, v in extra.items()]
    return env.make(DynamixelDriverNode, parameter_overrides=overrides)


def _capture(node):
    """The warning and info lines ``node`` logs from now on (still logged; one call site per
    severity, as rclpy requires)."""
    warnings, infos = [], []
    logger = node.get_logger()
    warning, info = logger.warning, logger.info
    logger.warning = lambda msg, **kw: warnings.append(msg) or warning(msg, **kw)
    logger.info = lambda msg, **kw: infos.append(msg) or info(msg, **kw)
    return warnings, infos


def _status(diags, name):
    return next(s for s in diags.messages[-1].status if s.name.endswith(f': {name}'))


@pytest.mark.timeout(90)
def test_port_lost_one_error_diagnostic_and_exit_code(tmp_path):
    """Before: the OSError escaped the timer (traceback), a second one came from the torque
    off at shutdown, and /diagnostics last said OK. Now: one error line naming the port, an
    ERROR diagnostic naming it, node.finished with a non-zero code, a clean destroy."""
    emu = ServoBusEmulator.of_model('ax18a', [1, 2]).start()
    try:
        with ros_env('dxl') as env:
            node = _node(env, emu, tmp_path, 1)
            errors = capture_errors(node)
            diags = Collector(env, DiagnosticArray, '/diagnostics')
            diags.wait_for(env, 1)
            emu.stop()
            assert env.spin_until(lambda: node.finished.done(), 30.0)
            assert node.finished.result() == EXIT_PORT_LOST != 0
            assert env.spin_until(lambda: any(
                s.level == DiagnosticStatus.ERROR and f'port {emu.port_name} lost' in s.message
                for m in diags.messages[-2:] for s in m.status), 10.0)
            assert len([e for e in errors if 'lost' in e]) == 1
            assert errors[0].startswith(f'port {emu.port_name} lost')
            node.destroy_node()            # no torque write on the dead port, no exception
            env.nodes.remove(node)
            env.executor.remove_node(node)
    finally:
        emu.stop()


@pytest.mark.timeout(90)
def test_power_cycled_servo_error_in_diagnostics_and_logged(tmp_path):
    """Before: j2 came back limp and /diagnostics said OK, torque_enabled=True, no log line.
    Now ERROR 'came back with torque off', torque_enabled False, warnings when it goes silent
    and comes back (once each), info when it answers again."""
    with ServoBusEmulator.of_model('xm430w350', [1, 2]) as emu, ros_env('dxl') as env:
        node = _node(env, emu, tmp_path, 2, silent_after=2, probe_interval_s=0.05)
        warnings, infos = _capture(node)
        diags = Collector(env, DiagnosticArray, '/diagnostics')
        diags.wait_for(env, 1)
        emu.inject(2, 'no_answer')
        assert env.spin_until(lambda: any('went silent' in w for w in warnings), 30.0)
        emu.power_cycle(2)
        assert env.spin_until(lambda: not node.bus.health()[1].silent, 30.0)
        n = len(diags.messages)
        assert env.spin_until(lambda: len(diags.messages) >= n + 2, 30.0)
        j2 = _status(diags, 'j2')
        assert j2.level == DiagnosticStatus.ERROR
        assert 'came back with torque off (power cycled or hardware error?)' in j2.message
        assert {kv.key: kv.value for kv in j2.values}['torque_enabled'] == 'False'
        assert _status(diags, 'j1').level == DiagnosticStatus.OK
        assert len([w for w in warnings if w.startswith('j2 (id 2) went silent')]) == 1
        assert len([w for w in warnings if 'came back with torque off' in w]) == 1
        assert any(i.startswith('j2 (id 2) answers again') for i in infos)
        assert emu.read_register(2, 'torque_enable') == 0


@pytest.mark.timeout(90)
def test_servo_back_as_another_model_left_out_of_joint_states_with_error(tmp_path):
    """A third review: j2 (AX-18A) goes silent and an MX-28 answers at its ID. Before: read
    with the AX-18A table and published on /joint_states (9.909 rad). Now it is left out of
    /joint_states, and /diagnostics has an ERROR naming both models."""
    from sensor_msgs.msg import JointState

    with ServoBusEmulator.of_model('ax18a', [1, 2]) as emu, ros_env('dxl') as env:
        node = _node(env, emu, tmp_path, 1, silent_after=2, probe_interval_s=0.05)
        warnings, _infos = _capture(node)
        diags = Collector(env, DiagnosticArray, '/diagnostics')
        joints = Collector(env, JointState, 'joint_states')
        diags.wait_for(env, 1)
        emu.inject(2, 'no_answer')
        assert env.spin_until(lambda: node.bus.health()[1].silent, 30.0)
        emu.replace(2, 'mx28', initial_position_rad=1.0)
        assert env.spin_until(lambda: 'j2' in node.bus.refused, 30.0)
        n, m = len(joints.messages), len(diags.messages)
        assert env.spin_until(lambda: len(diags.messages) >= m + 2
                              and len(joints.messages) >= n + 5, 30.0)
        assert all(list(js.name) == ['j1'] for js in joints.messages[n:])
        j2 = _status(diags, 'j2')
        assert j2.level == DiagnosticStatus.ERROR
        assert j2.message.startswith('left out: model changed: first detected as AX-18A (model '
                                     'number 18), now answers as MX-28 (model number 29)')
        assert _status(diags, 'j1').level == DiagnosticStatus.OK
        assert len([w for w in warnings if w.startswith('j2 (id 2) model changed')]) == 1
