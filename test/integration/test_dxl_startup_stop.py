"""dynamixel_driver: a stop (Ctrl-C, SIGTERM) during the torque-on pass at start-up.

An outside hardware review (finding 1): rclpy's signal handler shuts the context down but does
not interrupt the node's constructor, which went on turning torque on for every servo; the next
create_publisher raised, run_node took it for a clean stop with no node to destroy, and all
servos were left torqued, exit 0, nothing logged. Here the context is shut down from the
emulator at the moment servo K's Torque Enable 1 is written (before its reply), which is what
the signal handler does, at a deterministic point.
"""

from __future__ import annotations

import pytest
from harness import ros_env
from rclpy.executors import ExternalShutdownException
from rclpy.parameter import Parameter

from hexapod_bench_drivers.dynamixel_node import DynamixelDriverNode
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator

N = 6
K = 3


def _joints(tmp_path):
    path = tmp_path / 'joints.yaml'
    path.write_text('joints:\n' + ''.join(f'  j{i}: {{id: {i}}}\n' for i in range(1, N + 1)))
    return str(path)


def _capture(node_class, lines):
    """A node class whose logger calls are kept in ``lines`` as (level, message)."""
    class Captured(node_class):
        def get_logger(self):
            log = super().get_logger()
            for level in ('info', 'warning', 'error'):
                setattr(log, level, lambda msg, _lv=level, **kw: lines.append((_lv, msg)))
            return log

        def _stop_logger(self):      # the lines at a stop, too (they use '<node>.shutdown')
            return self.get_logger()
    return Captured


@pytest.mark.timeout(60)
@pytest.mark.parametrize('model,protocol', [('ax18a', 1), ('xl430', 2)])
def test_stop_during_torque_on_turns_nothing_more_on_and_releases(tmp_path, model, protocol):
    torque_on: list[int] = []     # servo ids in the order their Torque Enable 1 was written
    lines: list[tuple[str, str]] = []
    with ServoBusEmulator.of_model(model, range(1, N + 1)) as emu, ros_env('dxl_stop') as env:
        address = emu.servo(1).table.reg('torque_enable').address

        def on_write(servo, at, data):
            if at <= address < at + len(data) and data[address - at]:
                torque_on.append(servo.servo_id)
                if servo.servo_id == K:
                    env.context.shutdown()      # what rclpy's SIGINT/SIGTERM handler does

        for i in range(1, N + 1):
            emu.servo(i).write_hook = on_write
        with pytest.raises(ExternalShutdownException):
            _capture(DynamixelDriverNode, lines)(
                context=env.context, namespace=env.namespace, parameter_overrides=[
                    Parameter('port', value=emu.port_name), Parameter('protocol', value=protocol),
                    Parameter('joints_file', value=_joints(tmp_path)),
                    Parameter('timeout_margin_ms', value=20.0)])
        final = [emu.read_register(i, 'torque_enable') for i in range(1, N + 1)]
    # before: torque on for every servo, and left on
    assert torque_on == list(range(1, K + 1))
    assert final == [0] * N
    said = [m for _lv, m in lines]
    assert any(lv == 'warning' and 'stop requested while torque was turned on: not sent to '
               + ', '.join(f'j{i}' for i in range(K + 1, N + 1)) in m for lv, m in lines), said
    assert ('info', f'start-up stopped: torque off on {N} servo(s)') in lines, said


@pytest.mark.timeout(60)
def test_error_after_the_bus_opened_releases_it(tmp_path, monkeypatch):
    """Any error in the constructor once the bus is open and the torque on (here the
    command-publisher watch cannot be made) turns the torque off again, says so, and is
    raised as before."""
    from hexapod_bench_drivers import dynamixel_node

    lines: list[tuple[str, str]] = []
    with ServoBusEmulator.of_model('ax18a', range(1, N + 1)) as emu, ros_env('dxl_err') as env:
        cls = _capture(DynamixelDriverNode, lines)

        def broken(*a, **kw):
            assert all(emu.read_register(i, 'torque_enable') for i in range(1, N + 1))
            raise RuntimeError('no publisher today')
        monkeypatch.setattr(dynamixel_node, 'FirstPublisherWatch', broken)
        with pytest.raises(RuntimeError, match='no publisher today'):
            cls(context=env.context, namespace=env.namespace, parameter_overrides=[
                Parameter('port', value=emu.port_name), Parameter('protocol', value=1),
                Parameter('joints_file', value=_joints(tmp_path)),
                Parameter('timeout_margin_ms', value=20.0)])
        final = [emu.read_register(i, 'torque_enable') for i in range(1, N + 1)]
    assert final == [0] * N
    assert ('info', f'start-up stopped: torque off on {N} servo(s)') in lines
